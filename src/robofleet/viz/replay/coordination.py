"""The replay scene of a coordination run (RMTRACK and label flipping): the map, the
disturbance regions, planned paths, robots by state, who waits for whom, flips and the
disturbed robots."""

from __future__ import annotations

import numpy as np

from ...core.trace import Trace
from ..framing import run_title
from .building import (
    MAX_FRAMES,
    arrived_mask,
    goal_shapes,
    outcome_subtitle,
    replay_frames,
    speed_field,
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

STATUS_NAMES = ("moving", "waiting", "finished", "deadlocked")
STATUS_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728")


def replay_status(trace: Trace, steps: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """``(F, N)`` index into :data:`STATUS_NAMES` of the frames at simulation ``steps``
    (kept ``rows``; by default ``steps`` over ``record_every``): finished (arrived),
    deadlocked (from the deadlock event on), waiting (the recorded decision), else moving."""
    rows = steps // trace.record_every if rows is None else rows
    n = trace.positions.shape[1]
    waiting = trace.arrays.get("waiting", np.zeros((len(trace.positions), n, 1), bool))[..., 0]
    status = np.where(waiting[np.minimum(rows, len(waiting) - 1)], 1, 0).astype(np.uint8)
    status[arrived_mask(trace, steps)] = 2
    deadlocks = trace.events.take(trace.events.kind_mask("deadlock"))
    for i in range(len(deadlocks)):  # one event per deadlock of the run: few
        e = deadlocks[i]
        robots = [r for r in e.get("robots", [e.get("robot")]) if isinstance(r, int) and not isinstance(r, bool)]
        status[np.ix_(steps >= e["step"], robots)] = 3
    return status


def waits_for(trace: Trace, rows: np.ndarray, status: np.ndarray) -> list[list[tuple[int, int]]]:
    """Per frame, the pairs ``(i, j)``: robot ``i`` waits and its next planned position lies
    within two radii of the part of robot ``j``'s plan that ``j`` has not yet passed (``j``
    still has to cross where ``i`` wants to go). Derived from the plan and the progress."""
    plan, progress = trace.arrays.get("plan"), trace.arrays.get("progress")
    pairs: list[list[tuple[int, int]]] = [[] for _ in rows]
    if plan is None or progress is None:
        return pairs
    reach = 2.0 * float(trace.metadata["radius"])
    last = plan.shape[0] - 1
    x = progress[np.minimum(rows, len(progress) - 1), :, 0]
    cache: dict[tuple[int, int], np.ndarray] = {}
    for f, i in zip(*np.nonzero(status == 1)):
        target = int(min(x[f, i] + 1, last))
        if (i, target) not in cache:  # last plan index of each robot within reach of i's next position
            near = np.linalg.norm(plan - plan[target, i], axis=-1) < reach  # (K + 1, n)
            cache[(i, target)] = np.where(near.any(axis=0), last - np.argmax(near[::-1], axis=0), -1)
        latest = cache[(i, target)]
        pairs[f] += [(int(i), int(j)) for j in np.flatnonzero((latest >= x[f]) & (np.arange(len(latest)) != i))]
    return pairs


def relation_layer(pairs: list[list[tuple[int, int]]], coords: np.ndarray, group: str, style: dict) -> Layer:
    """Arrows from robot ``i`` to robot ``j`` for each frame's pairs."""
    segments = [[(*coords[f, i], *coords[f, j]) for i, j in frame_pairs] for f, frame_pairs in enumerate(pairs)]
    offsets, xy = per_frame(segments, 4)
    robots = np.array([i for frame_pairs in pairs for i, _ in frame_pairs], np.int64)
    return Layer("segments", group, {"offsets": offsets, "xy": xy, "robot": robots}, style)


def flip_pairs(trace: Trace, steps: np.ndarray, hold: int) -> list[list[tuple[int, int]]]:
    """Per frame, the flips (robot, other) of the last ``hold`` frames."""
    pairs: list[list[tuple[int, int]]] = [[] for _ in steps]
    events = trace.events
    flips = events.kind_mask("flip") & (events.column("other", -1) >= 0) if "other" in events.columns else np.zeros(len(events), bool)
    frames = frames_of_steps(events.steps[flips], steps)
    for frame, robot, other in zip(frames.tolist(), events.column("robot", -1)[flips].tolist(), events.column("other", -1)[flips].tolist()):
        for f in range(frame, min(len(steps), frame + hold)):
            pairs[f].append((int(robot), int(other)))
    return pairs


def disturbance_layer(trace: Trace, rows: np.ndarray) -> Layer | None:
    """Rings around the robots a disturbance stopped at each frame's step."""
    disturbed = trace.arrays.get("disturbed")
    if disturbed is None or not len(disturbed):
        return None
    hit = disturbed[np.minimum(rows, len(disturbed) - 1), :, 0]
    frame, robot = np.nonzero(hit)
    xy = trace.positions[rows][frame, robot]
    return Layer("marks", "disturbance", {"offsets": np.concatenate([[0], np.cumsum(hit.sum(axis=1))]), "xy": xy, "robot": robot},
                 {"marker": "ring", "stroke": "#8b0000", "size": 10, "width": 1.5})


COORDINATION_EVENTS = {"flip": "flip", "deadlock": "deadlock", "arrived": "arrived"}


def replay_scene(trace: Trace, max_frames: int = MAX_FRAMES) -> Scene:
    """The replay of a coordination run: the map with the disturbance regions, planned
    paths, robots coloured by state (moving, waiting, finished, deadlocked), arrows from
    each waiting robot to the robots it waits for, flips and the disturbed robots."""
    n_states = len(trace.positions)
    rows, steps = replay_frames(trace, max_frames)
    times = steps * float(trace.metadata.get("dt", 1.0))
    coords = trace.positions[rows]
    status = replay_status(trace, steps, rows)
    shapes = workspace_shapes(trace.workspace)
    plan = trace.arrays.get("plan")
    if plan is not None:
        shapes += [Shape("polyline", "planned paths", plan[:, i], {"stroke": "robot", "width": 1, "dash": [2, 3], "alpha": 0.8}, robot=i)
                   for i in range(plan.shape[1])]
    shapes += goal_shapes(np.asarray(trace.metadata.get("goals", coords[-1]), float))
    hold = max(1, len(steps) // 60)
    layers = [relation_layer(waits_for(trace, rows, status), coords, "waits for", {"stroke": "#ff7f0e", "width": 1.5, "arrow": True}),
              relation_layer(flip_pairs(trace, steps, hold), coords, "flips", {"stroke": "#9467bd", "width": 3, "arrow": True, "alpha": 0.8})]
    layers += [la for la in (disturbance_layer(trace, rows),) if la is not None]
    progress = trace.arrays.get("progress")
    fields = [speed_field(coords, times, "units/s")]
    if progress is not None:
        fields.append(Field("plan step reached", progress[np.minimum(rows, len(progress) - 1), :, 0].astype(float), digits=0))
    scene = Scene("coordination", run_title(trace), outcome_subtitle(trace, ("success", "deadlock", "flips", "mean_travel_time")),
                  steps, times, coords, [View("map (x, y)", (0, 1), ("x [map units]", "y [map units]"), *_map_extent(trace))],
                  radius=float(trace.metadata["radius"]), length_unit="map units",
                  status=status, statuses=[{"name": s, "color": c} for s, c in zip(STATUS_NAMES, STATUS_COLORS)],
                  fields=fields, shapes=shapes, layers=layers, events=trace_events(trace, steps, COORDINATION_EVENTS),
                  trail=0, notes=stride_note(rows, n_states, trace.record_every))
    present = set(scene.groups())
    scene.legend = [legend_entry(f"robot {s}", color=c, marker="circle") for s, c in zip(STATUS_NAMES, STATUS_COLORS)
                    if (status == STATUS_NAMES.index(s)).any()]
    optional = {"planned paths": legend_entry("planned path", color="#1f77b4", marker="line", dash=True),
                "goals": legend_entry("goal", color="#1f77b4", marker="x"),
                "obstacles": legend_entry("obstacle", color="#808080", marker="square"),
                "disturbance": legend_entry("disturbance region / disturbed robot", color="#d62728", marker="ring"),
                "waits for": legend_entry("waits for (derived from the plan)", color="#ff7f0e", marker="arrow"),
                "flips": legend_entry("label flip (robot → other)", color="#9467bd", marker="arrow")}
    scene.legend += [row for g, row in optional.items() if g in present]
    return scene


def _map_extent(trace: Trace) -> tuple[np.ndarray, np.ndarray]:
    if trace.workspace is not None:
        return trace.workspace.bounds.min(axis=0), trace.workspace.bounds.max(axis=0)
    xy = trace.positions.reshape(-1, 2)
    return xy.min(axis=0), xy.max(axis=0)
