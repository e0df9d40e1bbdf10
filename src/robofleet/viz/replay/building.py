"""Pieces every family's ``replay_scene`` uses: which frames, the title, the workspace,
arrival, speeds and events (all computed from the trace, nothing drawn here)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from ...core.errors import ConfigError
from ...core.trace import Trace
from ...core.workspace import Workspace
from ..animation import frame_indices
from . import MAX_FRAMES
from .scene import Event, Field, Shape, frames_of_steps, legend_entry

ROBOT_FRAME_BUDGET = 4_000_000
"""Robot-frames embedded at most (10,000 robots: 400 frames)."""


def replay_steps(n_states: int, n_robots: int, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """The state indices shown: all of them, or evenly spaced ones (the last included)
    within ``max_frames`` and :data:`ROBOT_FRAME_BUDGET`."""
    if isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) or max_frames < 2:
        raise ConfigError(f"max_frames: expected an integer ≥ 2, received {max_frames!r}")
    limit = max(2, min(int(max_frames), ROBOT_FRAME_BUDGET // max(1, n_robots)))
    return np.asarray(frame_indices(n_states, limit), np.int64)


def stride_note(steps: np.ndarray, n_states: int) -> list[str]:
    """A note when not every recorded state is shown."""
    if len(steps) >= n_states:
        return []
    return [f"{len(steps)} of {n_states} recorded states shown (one in about {int(np.ceil(n_states / len(steps)))})"]


def outcome_subtitle(trace: Trace, keys: Iterable[str]) -> str:
    """``N robots · success=… · key=…`` from the run's summary (what was recorded)."""
    summary = trace.summary()
    shown = [f"{k}={_short(summary[k])}" for k in keys if k in summary and summary[k] is not None]
    return " · ".join([f"{trace.positions.shape[1]} robots", *shown])


def _short(value: Any) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)


def workspace_shapes(workspace: Workspace | None, *, regions: bool = True) -> list[Shape]:
    """Bounds (outline), obstacles (grey) and regions (red, labelled with their ``p``)."""
    if workspace is None:
        return []
    shapes = [Shape("polygon", "workspace", workspace.bounds, {"stroke": "#222222", "width": 1.2})]
    shapes += [Shape("polygon", "obstacles", o, {"fill": "#808080", "stroke": "#404040", "width": 1}) for o in workspace.obstacles]
    if regions:
        for region in workspace.regions:
            shapes.append(Shape("polygon", "disturbance", region.vertices, {"fill": "#d62728", "alpha": 0.2, "stroke": "#d62728", "width": 1}))
            p = region.attributes.get("probability")
            if p is not None:
                shapes.append(Shape("text", "disturbance", np.asarray(region.vertices).mean(axis=0, keepdims=True),
                                    {"fill": "#8b0000", "size": 12}, text=f"p = {p:g}"))
    return shapes


def arrived_mask(trace: Trace, steps: np.ndarray) -> np.ndarray:
    """``(F, N)``: robot arrived by the frame's state (``arrival_steps`` ≥ 0 and ≤ step)."""
    n = trace.positions.shape[1]
    arrival = np.asarray(trace.arrays.get("arrival_steps", np.full(n, -1)), np.int64)
    return (arrival[None, :] >= 0) & (steps[:, None] >= arrival[None, :])


def speed_field(coords: np.ndarray, times: np.ndarray, unit: str) -> Field:
    """Speed between a frame and the one before it (0 at the first frame)."""
    step = np.linalg.norm(np.diff(coords, axis=0), axis=-1)
    dt = np.diff(times)[:, None]
    speed = np.divide(step, dt, out=np.zeros_like(step), where=dt > 0)
    return Field("speed", np.concatenate([np.zeros((1, coords.shape[1])), speed]), unit)


def trace_events(trace: Trace, steps: np.ndarray, kinds: dict[str, str]) -> list[Event]:
    """The trace's events of ``kinds`` (kind → shown name) on their frames, with a short text."""
    out = []
    for e in trace.events:
        if e.get("kind") not in kinds:
            continue
        frame = int(frames_of_steps(np.array([int(e.get("step", 0))]), steps)[0])
        robot = int(e["robot"]) if isinstance(e.get("robot"), (int, np.integer)) else -1
        extra = ", ".join(f"{k} {v}" for k, v in e.items() if k not in ("step", "kind", "robot", "time") and not isinstance(v, (list, dict)))
        out.append(Event(frame, kinds[e["kind"]], robot, f"step {e.get('step')}" + (f", {extra}" if extra else "")))
    return out


def event_marks(events: list[Event], coords: np.ndarray, kinds: Iterable[str], hold: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offsets, points and robots of rings at the robots of ``events`` of ``kinds``, each
    shown for ``hold`` frames from its frame (the robot's position at each of them)."""
    wanted = set(kinds)
    n_frames = coords.shape[0]
    per_frame: list[list[tuple[float, float, int]]] = [[] for _ in range(n_frames)]
    for e in events:
        if e.kind in wanted and e.robot >= 0:
            for f in range(e.frame, min(n_frames, e.frame + hold)):
                per_frame[f].append((*coords[f, e.robot, :2], e.robot))
    counts = np.array([len(rows) for rows in per_frame])
    offsets = np.concatenate([[0], np.cumsum(counts)])
    rows = np.array([r for rows in per_frame for r in rows], float).reshape(-1, 3)
    return offsets, rows[:, :2], rows[:, 2].astype(np.int64)


def goal_shapes(goals: np.ndarray, view: int = 0, axes: tuple[int, int] = (0, 1)) -> list[Shape]:
    """One × per goal, in its robot's colour."""
    return [Shape("points", "goals", np.asarray(g, float)[list(axes)][None, :], {"marker": "x", "stroke": "robot", "size": 9, "width": 2},
                  view=view, robot=i) for i, g in enumerate(goals)]


def robot_legend(trace_robots: int, label: str = "robots (colour per robot)") -> dict[str, Any]:
    """The legend row of the robots themselves."""
    return legend_entry(label if trace_robots > 1 else "robot", color="#1f77b4", marker="circle")
