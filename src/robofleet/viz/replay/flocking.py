"""The replay scene of a flocking run (Gervasi & Prencipe 2001): the leader and the
followers, the slots of the estimated target, every cycle's Look and Move, and the team
in the leader's frame with the pattern."""

from __future__ import annotations

import numpy as np

from ...core.trace import Trace
from ..framing import run_title
from .building import (
    MAX_FRAMES,
    outcome_subtitle,
    replay_frames,
    speed_field,
    stride_note,
)
from .scene import (
    ROBOT_PALETTE,
    Field,
    Layer,
    Scene,
    Shape,
    View,
    legend_entry,
    per_frame,
)

LEADER_COLOR = "#000000"


def leader_frame(positions: np.ndarray, headings: np.ndarray, leader: int = 0) -> np.ndarray:
    """``(F, N, 2)`` positions in the leader's frame: x along its heading, y to its left."""
    d = positions - positions[:, leader:leader + 1]
    c, s = np.cos(headings)[:, None], np.sin(headings)[:, None]
    return np.stack([d[..., 0] * c + d[..., 1] * s, -d[..., 0] * s + d[..., 1] * c], axis=-1)


def cycle_items(trace: Trace, times: np.ndarray) -> tuple[list[list], list[list]]:
    """Per frame, the Move of every cycle under way at the frame's time (start → destination)
    and the Look of every cycle that looked since the previous frame."""
    moves: list[list] = [[] for _ in times]
    looks: list[list] = [[] for _ in times]
    events = trace.events
    cycles = events.take(events.kind_mask("cycle"))
    if not len(cycles):
        return moves, looks
    starts, destinations = cycles.columns["start"], cycles.columns["destination"]
    firsts = np.searchsorted(times, cycles.column("t_look", np.nan), side="left")
    lasts = np.searchsorted(times, cycles.column("t_end", np.nan), side="left")
    for i, (first, last, robot) in enumerate(zip(firsts.tolist(), lasts.tolist(), cycles.column("robot", -1).tolist())):
        start = starts.value(i)
        for f in range(first, min(last, len(times))):
            moves[f].append((*start, *destinations.value(i), robot))
        if first < len(times):
            looks[first].append((*start, robot))
    return moves, looks


def items_layer(kind: str, group: str, items: list[list], width: int, style: dict) -> Layer:
    """A per-frame layer from rows ``(*coordinates, robot)``."""
    offsets, rows = per_frame(items, width + 1)
    return Layer(kind, group, {"offsets": offsets, "xy": rows[:, :width], "robot": rows[:, width].astype(np.int64)}, style)


def replay_scene(trace: Trace, max_frames: int = MAX_FRAMES) -> Scene:
    """The replay of a flocking run: the leader (black triangle along its heading) and the
    followers with trails, the slots of the estimated target, every cycle's Look (ring)
    and Move (line to its destination), and a second view in the leader's frame with
    the pattern."""
    n_states, n = trace.positions.shape[:2]
    rows, steps = replay_frames(trace, max_frames)
    times = np.asarray(trace.arrays["time"], float)[rows]
    pos = trace.positions[rows]
    heading = np.asarray(trace.arrays["leader_heading"], float)[rows]
    leader = int(trace.metadata.get("leader_index", 0))
    local = leader_frame(pos, heading, leader)
    pattern = np.asarray(trace.metadata.get("pattern", []), float).reshape(-1, 2)
    lo, hi = pos.reshape(-1, 2).min(axis=0) - 20, pos.reshape(-1, 2).max(axis=0) + 20
    span = np.vstack([pattern, [[0.0, 0.0]]])
    pad = 0.5 * float(np.ptp(span, axis=0).max() or 50.0)
    views = [View("plane (x, y)", (0, 1), ("x [units]", "y [units]"), lo, hi),
             View("leader's frame (x along its heading)", (0, 1), ("forward [units]", "left [units]"), span.min(axis=0) - pad,
                  span.max(axis=0) + pad, source="leader_frame")]
    targets = np.asarray(trace.arrays["estimated_target"], float)[rows]
    moves, looks = cycle_items(trace, times)
    layers = [Layer("marks", "estimated target (slots)", {"offsets": np.arange(len(steps) + 1) * targets.shape[1],
                                                          "xy": targets.reshape(-1, 2), "robot": np.full(targets.shape[0] * targets.shape[1], -1)},
                    {"marker": "ring", "stroke": "#808080", "size": 12, "width": 1}),
              items_layer("segments", "Move (to its destination)", moves, 4, {"stroke": "robot", "width": 1, "dash": [4, 3], "alpha": 0.7}),
              items_layer("marks", "Look", looks, 2, {"marker": "ring", "stroke": "robot", "size": 9, "width": 1.5})]
    shapes = [Shape("points", "pattern", pattern, {"marker": "ring", "stroke": "#808080", "size": 14, "width": 1.5}, view=1),
              Shape("points", "pattern", np.zeros((1, 2)), {"marker": "plus", "stroke": LEADER_COLOR, "size": 12, "width": 1.5}, view=1)]
    palette = (*ROBOT_PALETTE[:10], LEADER_COLOR)
    colors = np.array([10 if i == leader else (i - 1) % 10 for i in range(n)])
    headings = np.full((len(steps), n), np.nan)
    headings[:, leader] = heading
    fields = [speed_field(pos, times, "units per time unit"), Field("heading", headings, "rad"),
              Field("Δe (team)", np.asarray(trace.arrays["delta_e"], float)[rows], "units"),
              Field("Δr (team)", np.asarray(trace.arrays["delta_r"], float)[rows], "units")]
    r = trace.results
    subtitle = outcome_subtitle(trace, ("success",)) + (f" · Δe={r['delta_e_final']:.2f}, Δr={r['delta_r_final']:.2f}, ξ={r['xi']:.2f}"
                                                        if {"delta_e_final", "delta_r_final", "xi"} <= set(r) else "")
    scene = Scene("flocking", run_title(trace), subtitle, steps, times, pos, views, radius=0.0, point_px=5.0,
                  time_unit="time units", length_unit="units", palette=palette, robot_colors=colors,
                  robot_names=["leader" if i == leader else f"follower {i}" for i in range(n)],
                  robot_markers=["triangle" if i == leader else "circle" for i in range(n)], fields=fields,
                  coordinates={"leader_frame": local}, shapes=shapes, layers=layers, trail=60,
                  notes=stride_note(rows, n_states, trace.record_every))
    present = set(scene.groups())
    scene.legend = [legend_entry("leader (along its heading)", color=LEADER_COLOR, marker="triangle"),
                    legend_entry("follower (one colour each)", color=palette[0], marker="circle")]
    optional = {"estimated target (slots)": legend_entry("slot of the estimated target", color="#808080", marker="ring"),
                "Move (to its destination)": legend_entry("Move: from its Look position to its destination", color=palette[0], marker="line", dash=True),
                "Look": legend_entry("Look (a cycle starts)", color=palette[0], marker="ring"),
                "pattern": legend_entry("pattern (leader's frame view)", color="#808080", marker="ring")}
    scene.legend += [row for g, row in optional.items() if g in present]
    return scene
