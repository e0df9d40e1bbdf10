"""Pieces every family's ``replay_scene`` uses: which frames, the title, the workspace,
arrival, speeds and events (all computed from the trace, nothing drawn here).

Frames and ``record_every``: a trace keeps rows 0, 1, 2, … of states after steps 0, k,
2k, … (k = ``trace.record_every``). A replay shows some of those rows
(:func:`replay_frames`): frame ``f`` shows row ``rows[f]``, the state after step
``steps[f] = rows[f]·k``, at time ``steps[f]·dt``. Events keep their own step: an event
of step ``s`` goes to the first frame whose step is ≥ ``s`` (the frame covering the steps
since the one before it; the last frame takes the steps after it), so a frame's events
are those of the steps it covers. Everything is computed from arrays: no per-event
Python object is made, whatever the number of events."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from ...core.errors import ConfigError
from ...core.trace import Trace
from ...core.workspace import Workspace
from ..framing import frame_indices
from . import MAX_FRAMES
from .scene import Field, SceneEvents, Shape, frames_of_steps, legend_entry

ROBOT_FRAME_BUDGET = 4_000_000
"""Robot-frames embedded at most (10,000 robots: 400 frames)."""


def replay_steps(n_states: int, n_robots: int, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """The state indices shown: all of them, or evenly spaced ones (the last included)
    within ``max_frames`` and :data:`ROBOT_FRAME_BUDGET`."""
    if isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) or max_frames < 2:
        raise ConfigError(f"max_frames: expected an integer ≥ 2, received {max_frames!r}")
    limit = max(2, min(int(max_frames), ROBOT_FRAME_BUDGET // max(1, n_robots)))
    return np.asarray(frame_indices(n_states, limit), np.int64)


def replay_frames(trace: Trace, max_frames: int = MAX_FRAMES) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, steps)``: the kept rows shown (:func:`replay_steps`) and the simulation
    step of each (row × ``record_every``)."""
    n_states, n = trace.positions.shape[:2]
    rows = replay_steps(n_states, n, max_frames)
    return rows, rows * trace.record_every


def stride_note(rows: np.ndarray, n_states: int, record_every: int = 1) -> list[str]:
    """A note when not every step is shown (rows subsampled, or a run recorded every k-th step)."""
    notes = [f"states recorded every {record_every} steps"] if record_every > 1 else []
    if len(rows) >= n_states:
        return notes
    return notes + [f"{len(rows)} of {n_states} recorded states shown (one in about {int(np.ceil(n_states / len(rows)))})"]


def steps_per_frame(steps: np.ndarray) -> float:
    """Simulation steps between two frames, on average (1 for a single frame)."""
    return max(1.0, float(steps[-1] - steps[0]) / max(1, len(steps) - 1))


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


FRAME_BLOCK = 64
"""Frames computed together by the per-frame fields (bounding their temporaries)."""


def frame_blocks(n_frames: int) -> list[slice]:
    """Consecutive slices of at most :data:`FRAME_BLOCK` frames covering ``n_frames``."""
    return [slice(start, min(n_frames, start + FRAME_BLOCK)) for start in range(0, n_frames, FRAME_BLOCK)]


def speed_field(coords: np.ndarray, times: np.ndarray, unit: str) -> Field:
    """Speed between a frame and the one before it (0 at the first frame), over the time
    between them (``record_every`` and subsampled frames included)."""
    speed = np.zeros(coords.shape[:2], np.float32)
    gaps = np.diff(np.asarray(times, float))
    for block in frame_blocks(len(coords) - 1):
        moved = np.linalg.norm(coords[block.start + 1:block.stop + 1] - coords[block], axis=-1)
        dt = gaps[block][:, None]
        speed[block.start + 1:block.stop + 1] = np.divide(moved, dt, out=np.zeros_like(moved), where=dt > 0)
    return Field("speed", speed, unit)


SKIPPED_FIELDS = ("step", "kind", "robot", "time")
"""Event fields not repeated in an event's text (shown otherwise)."""


def trace_events(trace: Trace, steps: np.ndarray, kinds: dict[str, str]) -> SceneEvents:
    """The trace's events of ``kinds`` (kind → shown name) on their frames (the first
    frame whose step is ≥ the event's), with the robot, the step and a short text of the
    other scalar fields; computed by column."""
    events = trace.events
    chosen = np.flatnonzero(events.kind_mask(*kinds))
    picked = events.take(chosen)
    names = list(dict.fromkeys(kinds[k] for k in picked.kinds if k in kinds))
    table = np.array([names.index(kinds[k]) if k in kinds else -1 for k in picked.kinds], np.int64)  # -1: not chosen
    robot = picked.column("robot", -1) if "robot" in picked.columns and picked.columns["robot"].kind == "integer" else np.full(len(picked), -1)
    texts, text = event_texts(picked)
    return SceneEvents(frames_of_steps(picked.steps, steps), table[picked.codes] if len(table) else np.zeros(0, np.int64),
                       np.asarray(robot, np.int64), picked.steps, text, tuple(names), texts).by_frame()


def event_texts(events) -> tuple[tuple[str, ...], np.ndarray]:
    """``(texts, codes)``: per event ``name value, …`` of its scalar fields but those of
    :data:`SKIPPED_FIELDS` (code ``-1``: none); made only for events having such a field."""
    shown = [(name, c) for name, c in events.columns.items()
             if name not in SKIPPED_FIELDS and c.offsets is None and c.kind != "json"]
    codes = np.full(len(events), -1, np.int64)
    if not shown:
        return (), codes
    having = np.zeros(len(events), bool)
    for _, c in shown:
        having |= c.mask(len(events))
    table: dict[str, int] = {}
    for i in np.flatnonzero(having).tolist():
        text = ", ".join(f"{name} {c.value(i)}" for name, c in shown if c.has(i))
        codes[i] = table.setdefault(text, len(table))
    return tuple(table), codes


def sorted_unique(keys: np.ndarray, bound: int) -> np.ndarray:
    """``np.unique(keys)`` for integers in ``[0, bound)``: through a mark per possible key
    (linear time) when ``bound`` is at most a few times the number of keys, else by sorting."""
    if bound <= 8 * len(keys) + 1024:
        seen = np.zeros(bound, bool)
        seen[keys] = True
        return np.flatnonzero(seen)
    return np.unique(keys)


def event_marks(events: SceneEvents, coords: np.ndarray, kinds: Iterable[str], hold: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offsets, points and robots of rings at the robots of ``events`` of ``kinds``, each
    shown for ``hold`` frames from its frame (the robot's position at each of them; one
    ring per robot and frame)."""
    n_frames, n_robots = coords.shape[:2]
    chosen = events.of_kinds(list(kinds)) & (events.robot >= 0)
    frame, robot = events.frame[chosen], events.robot[chosen]
    shown = (frame[:, None] + np.arange(max(1, hold))[None, :]).reshape(-1)
    robots = np.repeat(robot, max(1, hold))
    keep = shown < n_frames
    key = sorted_unique(shown[keep] * n_robots + robots[keep], n_frames * n_robots)  # by frame, then robot
    frames, robots = key // n_robots, key % n_robots
    offsets = np.concatenate([[0], np.cumsum(np.bincount(frames, minlength=n_frames))])
    return offsets, coords[frames, robots, :2].reshape(-1, 2), robots.astype(np.int64)


def goal_shapes(goals: np.ndarray, view: int = 0, axes: tuple[int, int] = (0, 1)) -> list[Shape]:
    """One × per goal, in its robot's colour."""
    return [Shape("points", "goals", np.asarray(g, float)[list(axes)][None, :], {"marker": "x", "stroke": "robot", "size": 9, "width": 2},
                  view=view, robot=i) for i, g in enumerate(goals)]


def robot_legend(trace_robots: int, label: str = "robots (colour per robot)") -> dict[str, Any]:
    """The legend row of the robots themselves."""
    return legend_entry(label if trace_robots > 1 else "robot", color="#1f77b4", marker="circle")
