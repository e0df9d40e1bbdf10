"""The replay scene of an avoidance run (B-UAVC, Zhu, Brito & Alonso-Mora 2022): robots,
trails, goals, obstacles, the cells of the robots not yet arrived, 3σ ellipses of the
estimates, headings and deadlock events; 3-D runs as a top and a side view."""

from __future__ import annotations

import numpy as np

from ...core.trace import Trace
from ..framing import run_title
from ..avoidance_geometry import (
    TRAIL_STEPS,
    box_footprint,
    cell_polygons,
    clip_region,
    height_range,
    is_three_d,
    uncertainty_ellipse,
    view_extent,
)
from .building import (
    MAX_FRAMES,
    frame_blocks,
    arrived_mask,
    event_marks,
    goal_shapes,
    outcome_subtitle,
    replay_frames,
    speed_field,
    steps_per_frame,
    stride_note,
    trace_events,
    workspace_shapes,
)
from .scene import Field, Layer, Scene, Shape, View, legend_entry


def cell_layer(trace: Trace, rows: np.ndarray, arrived: np.ndarray) -> Layer | None:
    """The cells of the robots not yet arrived at each frame (none when not recorded)."""
    if "cell_A" not in trace.arrays or "cell_b" not in trace.arrays or not len(trace.arrays["cell_A"]):
        return None
    A, b = trace.arrays["cell_A"], trace.arrays["cell_b"]
    rows = np.minimum(rows, len(A) - 1)
    frame, robot = np.nonzero(~arrived)
    counts, vertices = cell_polygons(A[rows[frame], robot], b[rows[frame], robot], clip_region(trace))
    drawn = counts > 0
    per_frame = np.bincount(frame[drawn], minlength=len(rows))
    return Layer("polygons", "cells", {
        "offsets": np.concatenate([[0], np.cumsum(per_frame)]), "polygon": np.concatenate([[0], np.cumsum(counts[drawn])]),
        "vertices": vertices, "robot": robot[drawn]}, {"fill": "robot", "alpha": 0.15, "stroke": "robot", "width": 0.8})


def ellipse_layer(trace: Trace, rows: np.ndarray) -> Layer | None:
    """3σ ellipses of the position estimates (2-D runs whose ``robot_cov`` is known)."""
    cov, estimates = trace.metadata.get("robot_cov"), trace.arrays.get("estimates")
    if cov is None or estimates is None or not len(estimates) or is_three_d(trace):
        return None
    width, height, angle = uncertainty_ellipse(cov, 3.0)
    F, N = len(rows), estimates.shape[1]
    centres = np.empty((F, N, 2), np.float32)  # as embedded
    for block in frame_blocks(F):
        centres[block] = estimates[np.minimum(rows[block], len(estimates) - 1), :, :2]
    return Layer("ellipses", "uncertainty (3σ)", {
        "offsets": np.arange(F + 1) * N, "xy": centres.reshape(-1, 2),
        "shape": np.tile(np.array([width, height, np.radians(angle)], np.float32), (F * N, 1)),
        "robot": np.tile(np.arange(N, dtype=np.int32), F)},
        {"stroke": "robot", "width": 1, "dash": [4, 3]})


def heading_layer(trace: Trace, rows: np.ndarray, view: int = 0) -> Layer | None:
    """A short line along each robot's heading (when recorded)."""
    headings = trace.arrays.get("headings")
    if headings is None:
        return None
    h = headings[rows]
    xy = trace.positions[rows, :, :2]
    length = 1.8 * float(trace.metadata["radius"])
    tips = xy + length * np.stack([np.cos(h), np.sin(h)], axis=-1)
    finite = np.isfinite(h)
    frame, robot = np.nonzero(finite)
    return Layer("segments", "headings", {
        "offsets": np.concatenate([[0], np.cumsum(finite.sum(axis=1))]),
        "xy": np.concatenate([xy[frame, robot], tips[frame, robot]], axis=1), "robot": robot}, {"stroke": "#000000", "width": 1.2}, view)


def replay_views(trace: Trace) -> list[View]:
    """Top view (x, y); for 3-D runs also a side view (x, z)."""
    lo, hi = view_extent(trace)
    views = [View("top view (x, y)" if is_three_d(trace) else "workspace (x, y)", (0, 1), ("x [m]", "y [m]"), lo, hi)]
    if is_three_d(trace):
        z0, z1 = height_range(trace)
        views.append(View("side view (x, z)", (0, 2), ("x [m]", "z [m]"), [lo[0], z0], [hi[0], z1]))
    return views


def replay_shapes(trace: Trace, views: list[View]) -> list[Shape]:
    """Workspace, obstacles and boxes (footprints from above, rectangles from the side), goals."""
    lo, hi = view_extent(trace)
    shapes = workspace_shapes(trace.workspace) if trace.workspace is not None and not is_three_d(trace) else [
        Shape("polygon", "workspace", np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]]), {"stroke": "#222222", "width": 1.2})]
    for box in trace.metadata.get("boxes") or []:
        footprint = box_footprint(box["center"], box["size"], box.get("yaw", 0.0))
        shapes.append(Shape("polygon", "obstacles", footprint, {"fill": "#808080", "stroke": "#404040", "width": 1}))
        if len(views) > 1:
            x0, x1 = footprint[:, 0].min(), footprint[:, 0].max()
            z0, z1 = box["center"][2] - box["size"][2] / 2, box["center"][2] + box["size"][2] / 2
            shapes.append(Shape("polygon", "obstacles", np.array([[x0, z0], [x1, z0], [x1, z1], [x0, z1]]),
                                {"fill": "#808080", "stroke": "#404040", "width": 1, "alpha": 0.6}, view=1))
    goals = np.asarray(trace.metadata["goals"], float)
    for v, view in enumerate(views):
        shapes += goal_shapes(goals, v, view.axes)
    return shapes


def replay_fields(trace: Trace, rows: np.ndarray, times: np.ndarray, positions: np.ndarray | None = None) -> list[Field]:
    """Hover values: speed, heading, estimate error, whether the estimate lies in the cell
    (``positions``: the frames' positions, if already taken)."""
    positions = trace.positions[rows] if positions is None else positions
    fields = [speed_field(positions, times, "m/s")]
    if "headings" in trace.arrays:
        fields.append(Field("heading", trace.arrays["headings"][rows], "rad"))
    estimates = trace.arrays.get("estimates")
    if estimates is not None and len(estimates):
        error = np.empty(positions.shape[:2], np.float32)
        for block in frame_blocks(len(rows)):
            error[block] = np.linalg.norm(estimates[np.minimum(rows[block], len(estimates) - 1)] - positions[block], axis=-1)
        fields.append(Field("estimate error", error, "m"))
    inside = trace.arrays.get("estimate_in_cell")
    if inside is not None and len(inside):
        fields.append(Field("estimate in its cell", inside[np.minimum(rows, len(inside) - 1)].astype(float), labels=("no", "yes")))
    return fields


AVOIDANCE_EVENTS = {"deadlock": "deadlock", "empty_cell": "empty cell", "arrived": "arrived", "collision": "collision"}


def replay_scene(trace: Trace, max_frames: int = MAX_FRAMES) -> Scene:
    """The replay of an avoidance run: robots (true discs), trails, goals, obstacles,
    B-UAVC cells of the robots not yet arrived, 3σ ellipses of the estimates, headings and
    deadlock events; 3-D runs as a top and a side view."""
    n_states = len(trace.positions)
    rows, steps = replay_frames(trace, max_frames)
    dt = float(trace.metadata["dt"])
    times = steps * dt
    arrived = arrived_mask(trace, steps)
    views = replay_views(trace)
    events = trace_events(trace, steps, AVOIDANCE_EVENTS)
    layers = [la for la in (cell_layer(trace, rows, arrived), ellipse_layer(trace, rows), heading_layer(trace, rows)) if la is not None]
    stride = steps_per_frame(steps)
    positions = trace.positions[rows]
    offsets, xy, robots = event_marks(events, positions, ("deadlock",), hold=max(1, round(1.0 / dt / stride)))
    layers.append(Layer("marks", "deadlock events", {"offsets": offsets, "xy": xy, "robot": robots},
                        {"marker": "ring", "stroke": "#d62728", "size": 14, "width": 2}))
    scene = Scene("avoidance", run_title(trace), outcome_subtitle(trace, ("success", "collisions", "obstacle_collisions", "makespan")),
                  steps, times, positions, views, radius=float(trace.metadata["radius"]),
                  status=arrived.astype(np.uint8), statuses=[{"name": "moving"}, {"name": "arrived", "alpha": 0.45}],
                  fields=replay_fields(trace, rows, times, positions), shapes=replay_shapes(trace, views), layers=layers,
                  events=events, trail=int(np.ceil(TRAIL_STEPS / stride)), notes=stride_note(rows, n_states, trace.record_every))
    scene.solids = list(trace.metadata.get("boxes") or []) if is_three_d(trace) else []
    scene.legend = replay_legend(scene)
    return scene


def replay_legend(scene: Scene) -> list[dict]:
    """Legend rows of what the scene shows."""
    present = set(scene.groups())
    rows = [legend_entry("robot (true position, one colour each; faded: arrived)", color="#1f77b4", marker="circle")]
    table = {"goals": legend_entry("goal", color="#1f77b4", marker="x"),
             "cells": legend_entry("B-UAVC cell (robots not arrived)", color="#1f77b4", marker="square"),
             "uncertainty (3σ)": legend_entry("3σ ellipse of the position estimate", color="#1f77b4", marker="ellipse", dash=True),
             "headings": legend_entry("heading", color="#000000", marker="line"),
             "obstacles": legend_entry("obstacle", color="#808080", marker="square"),
             "deadlock events": legend_entry("deadlock detected", color="#d62728", marker="ring")}
    return rows + [table[g] for g in table if g in present]
