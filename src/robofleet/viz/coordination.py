"""Plots and animations of the coordination family (the label-flipping deadlock paper (2021)): Fig. 6 panels, the map with
planned trajectories and a run's final state (Fig. 1), and an animation of a run (waiting
robots highlighted).

Reads result tables and traces only (``robofleet.core`` and matplotlib); never imports an
algorithm. ``plot_trace`` and ``animate_trace`` take any coordination trace.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Circle
from matplotlib.patches import Polygon as PolygonPatch

from ..core.trace import Trace
from ..core.workspace import Workspace
from .animation import (
    FrameTitle,
    fit_canvas,
    frame_indices,
    outside_legend,
    proxy,
    run_title,
    save_figure,
    save_gif,
    workspace_figure,
)

if TYPE_CHECKING:
    import pandas as pd

PANELS = (
    ("mean_travel_time", "(a) average travel time [s]"),
    ("decision_ms_per_test", "(b) flip-decision time [ms per test]"),
    ("flips", "(c) number of flips"),
    ("finished_share", "(d) finished without deadlock [share]"),
)
STYLES = {
    "RMTRACK": ("tab:gray", "-", "o"), "RMTRACK (checked)": ("tab:gray", "--", "o"),
    "RMTRACK+TFF": ("tab:blue", "-", "s"), "RMTRACK+TFF (checked)": ("tab:blue", "--", "s"),
    "RMTRACK+TFA": ("tab:red", "-", "^"), "RMTRACK+TFA (checked)": ("tab:red", "--", "^"),
}


def plot_fig6(summary: pd.DataFrame, path: str | Path) -> Path:
    """Four panels of Fig. 6 from the per-(robot count, variant) summary table.

    ``summary`` (a pandas DataFrame) has columns ``n_robots``, ``variant`` and the panels' columns
    (``mean_travel_time``, ``decision_ms_per_test``, ``flips``, ``finished_share``).
    """
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    for ax, (column, title) in zip(axes.ravel(), PANELS):
        for variant in summary["variant"].drop_duplicates():  # in the table's order
            color, line, marker = STYLES.get(str(variant), ("k", "-", "."))
            g = summary[summary["variant"] == variant].sort_values("n_robots")
            ax.plot(g["n_robots"], g[column], color=color, linestyle=line, marker=marker, label=str(variant))
        ax.set_title(title)
        ax.set_xlabel("number of robots")
        ax.set_xticks(sorted(summary["n_robots"].unique()))
        ax.grid(alpha=0.3)
    axes[1, 1].set_ylim(-0.05, 1.05)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("reproduce rmtrack: Fig. 6 of the label-flipping deadlock paper (X-plus-corridor map)", fontsize=11)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


PEER_STYLES = {
    "RMTRACK": ("tab:gray", "o"), "RMTRACK+TFF (checked)": ("tab:blue", "s"), "RMTRACK+TFA (checked)": ("tab:red", "^"),
    "BTPG": ("tab:green", "D"), "optimal": ("tab:purple", "*"),
}
PEER_PANELS = (
    ("waiting_removed", "unnecessary waiting removed vs RMTRACK [share]", "linear"),
    ("decision_ms_per_step", "decision time [ms per step]", "log"),
)


def plot_peers(summary: pd.DataFrame, path: str | Path) -> Path:
    """The peers comparison: per map (columns), the share of RMTRACK's unnecessary waiting
    each method removes and its decision time per step, against the robot count.

    ``summary`` has columns ``map``, ``n_robots``, ``method`` and the panels' columns
    (``waiting_removed``, ``decision_ms_per_step``).
    """
    maps = list(summary["map"].drop_duplicates()) or [""]
    fig, axes = plt.subplots(len(PEER_PANELS), len(maps), figsize=(5.5 * len(maps), 7.5), squeeze=False)
    for col, name in enumerate(maps):
        part = summary[summary["map"] == name]
        for row, (column, title, scale) in enumerate(PEER_PANELS):
            ax = axes[row, col]
            for method in part["method"].drop_duplicates():
                color, marker = PEER_STYLES.get(str(method), ("k", "."))
                g = part[part["method"] == method].sort_values("n_robots")
                values = g[column].where(g[column] > 0) if scale == "log" else g[column]
                ax.plot(g["n_robots"], values, color=color, marker=marker, label=str(method))
            ax.set_yscale(scale)
            ax.set_title(f"{name}: {title}", fontsize=9)
            ax.set_xlabel("number of robots")
            ax.set_xticks(sorted(part["n_robots"].unique()))
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("reproduce coordination-peers: RMTRACK, TFF, TFA (checked), BTPG, optimal on the same plans and disturbances",
                 fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def draw_workspace(ax: plt.Axes, workspace: Workspace) -> None:
    """Bounds, obstacles and regions (disturbance regions in red, labelled with ``p``)."""
    ax.add_patch(PolygonPatch(workspace.bounds, closed=True, facecolor="white", edgecolor="black", lw=1.2))
    for obstacle in workspace.obstacles:
        ax.add_patch(PolygonPatch(obstacle, closed=True, facecolor="0.6", edgecolor="black", lw=1.0))
    for region in workspace.regions:
        p = region.attributes.get("probability")
        ax.add_patch(PolygonPatch(region.vertices, closed=True, facecolor="red", alpha=0.25, edgecolor="red"))
        if p is not None:
            cx, cy = np.asarray(region.vertices).mean(axis=0)
            ax.text(cx, cy, f"p={p:g}", color="darkred", ha="center", va="center", fontsize=8)
    xmin, ymin = workspace.bounds.min(axis=0)
    xmax, ymax = workspace.bounds.max(axis=0)
    pad = 0.03 * max(xmax - xmin, ymax - ymin)
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_aspect("equal")
    ax.set_facecolor("0.85")


def plot_trace(trace: Trace, path: str | Path) -> Path:
    """The map with the planned trajectories (dotted), the starts (hollow discs) and the
    robots where the run ended (green finished, orange waiting, red deadlocked, blue moving);
    the canvas sized to the map (:func:`~.animation.fit_canvas`)."""
    fig, ax = workspace_figure(*map_corners(trace.workspace))
    draw_workspace(ax, trace.workspace)
    _draw_plan(ax, trace)
    radius = float(trace.metadata["radius"])
    for p in trace.positions[0]:
        ax.add_patch(Circle(p, radius, fill=False, edgecolor="tab:blue", lw=0.8))
    colors = final_colors(trace)
    for p, color in zip(trace.positions[-1], colors):
        ax.add_patch(Circle(p, radius, color=color, zorder=3))
    ax.set(xlabel="x [map units]", ylabel="y [map units]")
    ax.set_title(f"{run_title(trace)}\n{outcome_title(trace)}", fontsize=9)
    handles = [proxy("planned path", color="C0", ls=":"), proxy("start", color="tab:blue", marker="o", mfc="none")]
    handles += [proxy(f"end: {name}", color=c, marker="o") for name, c in zip(("moving", "waiting", "finished", "deadlocked"),
                                                                               ("tab:blue", "tab:orange", "tab:green", "tab:red")) if c in colors]
    handles += _map_handles(trace)
    outside_legend(ax, handles)
    return save_figure(fit_canvas(fig), path, dpi=110)


def map_corners(workspace: Workspace) -> tuple[np.ndarray, np.ndarray]:
    """Lower-left and upper-right corners of the map."""
    return workspace.bounds.min(axis=0), workspace.bounds.max(axis=0)


def _map_handles(trace: Trace) -> list:
    """Legend entries of the map's obstacles and disturbance regions, when present."""
    handles = []
    if trace.workspace is not None and len(trace.workspace.obstacles):
        handles.append(proxy("obstacle", color="0.6", marker="s", ms=9))
    if trace.workspace is not None and trace.workspace.regions:
        handles.append(proxy("disturbance region (p: stop probability)", color=(1, 0, 0, 0.25), marker="s", ms=9))
    return handles


def final_colors(trace: Trace) -> list[str]:
    """Each robot's colour in the last recorded row: finished, deadlocked, waiting or moving."""
    n = trace.positions.shape[1]
    finished = trace.arrays.get("arrival_steps", np.full(n, -1)) >= 0
    waiting = trace.arrays.get("waiting", np.zeros((1, n, 1), bool))[-1, :, 0]
    deadlocked = {r for e in trace.events if e.get("kind") == "deadlock" for r in e.get("robots", [])}
    return ["tab:green" if finished[i] else "tab:red" if i in deadlocked else "tab:orange" if waiting[i] else "tab:blue"
            for i in range(n)]


def outcome_title(trace: Trace) -> str:
    """``method · n robots · outcome`` from the trace's metadata and results."""
    r, md = trace.results, trace.metadata
    outcome = "deadlock" if r.get("deadlock") else "finished" if r.get("finished") else "step budget spent"
    travel = r.get("mean_travel_time")
    tail = f", mean travel time {travel:.1f} s" if isinstance(travel, float) and np.isfinite(travel) else ""
    return f"{md.get('method', '')} · {md.get('n_robots', trace.positions.shape[1])} robots · {outcome}{tail} · {r.get('flips', 0)} flips"


def _draw_plan(ax, trace: Trace) -> None:
    plan = trace.arrays.get("plan")
    if plan is None:
        return
    colors = plt.cm.tab20(np.linspace(0, 1, plan.shape[1]))
    for i in range(plan.shape[1]):
        ax.plot(plan[:, i, 0], plan[:, i, 1], linestyle=":", lw=0.9, color=colors[i])


def animate_trace(trace: Trace, path: str | Path, max_frames: int = 150, fps: int = 12) -> Path:
    """GIF of a run: robots (blue moving, orange waiting, green finished), the disturbance
    region, the planned trajectories; deadlocked robots in red on the last frame."""
    positions = trace.positions
    waiting = trace.arrays.get("waiting", np.zeros(positions.shape[:2] + (1,), bool))[..., 0]
    progress = trace.arrays.get("progress")
    plan = trace.arrays.get("plan")
    lengths = _plan_lengths(plan) if plan is not None else None
    radius = float(trace.metadata["radius"])
    dt = float(trace.metadata.get("dt", 1.0))
    deadlocked = {r for e in trace.events if e.get("kind") == "deadlock" for r in e.get("robots", [])}
    fig, ax = workspace_figure(*map_corners(trace.workspace))
    draw_workspace(ax, trace.workspace)
    _draw_plan(ax, trace)
    ax.set(xlabel="x [map units]", ylabel="y [map units]")
    outside_legend(ax, [proxy(f"robot {name}", color=c, marker="o", ms=8) for name, c in
                        zip(("moving", "waiting", "finished", "deadlocked (last frame)"), ("tab:blue", "tab:orange", "tab:green", "tab:red"))
                        if name != "deadlocked (last frame)" or deadlocked] + [proxy("planned path", color="C0", ls=":")] + _map_handles(trace))
    discs = [ax.add_patch(Circle(p, radius, color="tab:blue", zorder=3)) for p in positions[0]]
    title = FrameTitle(ax, run_title(trace))
    frames = frame_indices(len(positions), max_frames)
    last = frames[-1]

    def update(t):
        done = progress[t, :, 0] >= lengths if progress is not None and lengths is not None else np.zeros(len(discs), bool)
        for i, disc in enumerate(discs):
            disc.center = positions[t, i]
            if t == last and i in deadlocked:
                disc.set_color("tab:red")
            elif done[i]:
                disc.set_color("tab:green")
            elif waiting[min(t, len(waiting) - 1), i]:
                disc.set_color("tab:orange")
            else:
                disc.set_color("tab:blue")
        return [*discs, title.show(f"t = {t * dt:.1f} s · waiting: {int(waiting[min(t, len(waiting) - 1)].sum())}")]

    update(frames[0])
    fit_canvas(fig)  # to the map, the legend and the first frame's title
    return save_gif(fig, update, frames, path, fps=fps, blit=True)


def _plan_lengths(plan: np.ndarray) -> np.ndarray:
    """``K_i`` from a padded plan ``(K_max + 1, n, 2)``: last step where the robot still moves."""
    moved = np.any(plan != plan[-1:], axis=-1)  # (K+1, n)
    last = np.where(moved.any(axis=0), plan.shape[0] - 1 - np.argmax(moved[::-1], axis=0), -1)
    return last + 1
