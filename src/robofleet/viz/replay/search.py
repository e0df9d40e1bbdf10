"""The replay scene of a search run (Yang 2017): the area and its grid, visited vertices,
targets (found ones filled), robots (failed ones crossed out), their communication links
within r_c and the events."""

from __future__ import annotations

import numpy as np

from ...core.trace import Trace
from ..framing import run_title
from .building import (
    MAX_FRAMES,
    event_marks,
    outcome_subtitle,
    replay_frames,
    stride_note,
    trace_events,
    workspace_shapes,
)
from .scene import (
    Field,
    Layer,
    Scene,
    Shape,
    View,
    frames_of_steps,
    legend_entry,
    per_frame,
)

SEARCH_STATUSES = [{"name": "searching"}, {"name": "failed", "color": "#7f7f7f", "cross": True}]
SEARCH_EVENTS = {"target_found": "target found", "failure": "failure", "failure_detected": "failure detected",
                 "collision": "collision", "obstacle_collision": "obstacle collision", "stop": "stop broadcast"}


def first_visit_frames(trace: Trace, steps: np.ndarray) -> np.ndarray:
    """``(V,)``: the frame from which each grid vertex has been visited (``-1``: never),
    from the kept rows of ``vertex`` (row ``j``: step ``j · record_every``)."""
    n_vertices = len(trace.metadata.get("grid_points", []))
    vertex = trace.arrays["vertex"][..., 0]
    first = np.full(n_vertices, -1, np.int64)
    for row in range(len(vertex) - 1, -1, -1):  # the earliest row wins
        first[vertex[row]] = row
    return np.where(first >= 0, frames_of_steps(np.maximum(first, 0) * trace.record_every, steps), -1)


def found_target_frames(trace: Trace, steps: np.ndarray) -> np.ndarray:
    """``(T,)``: the frame each target was first found at (``-1``: never)."""
    n_targets = len(trace.metadata.get("targets", []))
    found = np.full(n_targets, -1, np.int64)
    events = trace.events
    chosen = events.kind_mask("target_found")
    if not chosen.any():
        return found
    targets, frames = events.column("target", -1)[chosen], frames_of_steps(events.steps[chosen], steps)
    for target, frame in zip(targets[::-1].tolist(), frames[::-1].tolist()):  # the first event of each target wins
        found[target] = frame
    return found


def failed_mask(trace: Trace, steps: np.ndarray) -> np.ndarray:
    """``(F, N)``: the robot has failed by the frame's step."""
    n = trace.positions.shape[1]
    failed = np.zeros((len(steps), n), bool)
    events = trace.events
    chosen = events.kind_mask("failure")
    for step, robot in zip(events.steps[chosen].tolist(), events.column("robot", -1)[chosen].tolist()):
        failed[steps >= step, robot] = True
    return failed


def message_links(coords: np.ndarray, failed: np.ndarray, r_c: float) -> list[list]:
    """Per frame, one segment per pair of live robots within the communication range ``r_c``."""
    links = []
    for xy, down in zip(coords, failed):
        d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)
        i, j = np.nonzero(np.triu(d <= r_c, 1) & ~down[:, None] & ~down[None, :])
        links.append([(*xy[a], *xy[b], a) for a, b in zip(i, j)])
    return links


def replay_scene(trace: Trace, max_frames: int = MAX_FRAMES) -> Scene:
    """The replay of a search run: the area, its grid (accessible vertices as dots,
    inaccessible as crosses), visited vertices, targets (found ones filled), the robots
    (failed ones crossed out), their communication links within r_c, and the events."""
    n_states = len(trace.positions)
    rows, steps = replay_frames(trace, max_frames)
    times = trace.arrays["time"][rows, 0, 0] if "time" in trace.arrays else steps.astype(float)
    coords = trace.positions[rows]
    md = trace.metadata
    points = np.asarray(md.get("grid_points", np.zeros((0, 2))), float).reshape(-1, 2)
    accessible = np.asarray(md.get("accessible", np.ones(len(points), bool)), bool)
    targets = np.asarray(md.get("targets", []), float).reshape(-1, 2)
    failed = failed_mask(trace, steps)
    shapes = workspace_shapes(trace.workspace)
    shapes += [Shape("points", "grid", points[accessible], {"marker": "dot", "fill": "#b0b0b0", "size": 3}),
               Shape("points", "grid", points[~accessible], {"marker": "x", "stroke": "#c8c8c8", "size": 5})]
    shapes += [Shape("points", "targets", targets, {"marker": "star", "stroke": "#dc143c", "size": 14, "width": 1})] if len(targets) else []
    events = trace_events(trace, steps, SEARCH_EVENTS)
    layers = [Layer("reveal", "visited vertices", {"xy": points, "frame": first_visit_frames(trace, steps)},
                    {"marker": "dot", "fill": "#2ca02c", "size": 6}),
              Layer("reveal", "targets found", {"xy": targets, "frame": found_target_frames(trace, steps)},
                    {"marker": "star", "fill": "#dc143c", "size": 14})]
    r_c = float((md.get("ranges") or {}).get("r_c", 0.0))
    if r_c > 0:
        layers.append(items_layer(message_links(coords, failed, r_c), "messages (links within r_c)",
                                  {"stroke": "#17becf", "width": 1.5, "alpha": 0.7}))
    hold = max(1, len(steps) // 40)
    for kinds, group, color in ((("target found",), "target found (broadcast)", "#dc143c"),
                                (("failure detected",), "failure detected", "#000000")):
        offsets, xy, robots = event_marks(events, coords, kinds, hold)
        layers.append(Layer("marks", group, {"offsets": offsets, "xy": xy, "robot": robots},
                            {"marker": "ring", "stroke": color, "size": 22, "width": 2}))
    fields = [Field("vertex", trace.arrays["vertex"][rows, :, 0].astype(float), digits=0),
              Field("visited vertices (team)", _visited_counts(trace, steps).astype(float), digits=0)]
    lo, hi = (np.array(trace.workspace.extent[:2]), np.array(trace.workspace.extent[2:])) if trace.workspace is not None else (
        coords.reshape(-1, 2).min(axis=0) - 1, coords.reshape(-1, 2).max(axis=0) + 1)
    scene = Scene("search", run_title(trace), outcome_subtitle(trace, ("success", "search_time", "found_targets", "visited_share")),
                  steps, times, coords, [View("area (x, y)", (0, 1), ("x [m]", "y [m]"), lo, hi)],
                  radius=float(md.get("radius", 0.0)), status=failed.astype(np.uint8), statuses=SEARCH_STATUSES,
                  fields=fields, shapes=shapes, layers=layers, events=events, trail=len(steps),
                  notes=stride_note(rows, n_states, trace.record_every))
    scene.legend = _search_legend(scene, failed.any())
    return scene


def items_layer(items: list[list], group: str, style: dict) -> Layer:
    """Segments from per-frame rows ``(x0, y0, x1, y1, robot)``."""
    offsets, rows = per_frame(items, 5)
    return Layer("segments", group, {"offsets": offsets, "xy": rows[:, :4], "robot": rows[:, 4].astype(np.int64)}, style)


def _visited_counts(trace: Trace, steps: np.ndarray) -> np.ndarray:
    first = first_visit_frames(trace, steps)
    return np.array([int(((first >= 0) & (first <= f)).sum()) for f in range(len(steps))])


def _search_legend(scene: Scene, any_failed: bool) -> list[dict]:
    present = set(scene.groups())
    rows = [legend_entry("robot (one colour each)", color="#1f77b4", marker="circle")]
    if any_failed:
        rows.append(legend_entry("failed robot (crossed out)", color="#7f7f7f", marker="x"))
    optional = {"grid": legend_entry("grid vertex (× inaccessible)", color="#b0b0b0", marker="dot"),
                "visited vertices": legend_entry("visited vertex", color="#2ca02c", marker="dot"),
                "targets": legend_entry("target (filled once found)", color="#dc143c", marker="star"),
                "messages (links within r_c)": legend_entry("communication link (within r_c)", color="#17becf", marker="line"),
                "target found (broadcast)": legend_entry("target found and broadcast", color="#dc143c", marker="ring"),
                "failure detected": legend_entry("failure detected by a neighbour", color="#000000", marker="ring"),
                "obstacles": legend_entry("obstacle", color="#808080", marker="square")}
    return rows + [row for g, row in optional.items() if g in present]
