"""Plots and animations of the ``search`` family (Yang 2017).

Reads traces and result tables only: :func:`plot_trace` (the routes, like Fig. 5),
:func:`plot_routes` (Figs. 5–6), :func:`animate_trace`, and from the reproduction's
tables Fig. 7 (:func:`plot_fig7`, mean search time with 95 % CIs) and the coverage study
(:func:`plot_coverage_ranges`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.patches import Polygon as PolygonPatch

from ..core.trace import Trace
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

ALGORITHM_ORDER = ("lfp", "ru", "rule1", "proposed")
MARKERS = {"lfp": "v", "ru": "s", "rule1": "^", "proposed": "o"}


def plot_fig7(summary: pd.DataFrame, path: str | Path) -> Path:
    """Mean search time against the number of robots, one line per algorithm (Fig. 7).

    ``summary`` has columns ``algorithm``, ``label``, ``n_robots``, ``mean_time``, ``ci95``.
    """
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for alg in [a for a in ALGORITHM_ORDER if a in set(summary["algorithm"])]:
        rows = summary[summary["algorithm"] == alg].sort_values("n_robots")
        ax.errorbar(rows["n_robots"], rows["mean_time"], yerr=rows["ci95"], marker=MARKERS.get(alg, "o"), capsize=3,
                    label=rows["label"].iloc[0])
    ax.set_xlabel("number of robots")
    ax.set_ylabel("mean search time [s] (log scale)")
    ax.set_yscale("log")
    ax.set_title("reproduce search: Fig. 7, search time, nine targets (mean ± 95 % CI)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend()
    return save_figure(fig, path, dpi=130, tight=True)


def plot_coverage_ranges(summary: pd.DataFrame, path: str | Path, columns: dict[str, float] | None = None) -> Path:
    """Detected share of ``A_d`` against the target-sensing range, one line per grid.

    ``columns`` maps summary columns to ``r_st / a`` values (default: every
    ``detected_at_rst_<x>a`` column), and ``detected_share`` is drawn at the scenario's range.
    """
    columns = columns or {c: float(c.split("_")[-1][:-1]) for c in summary.columns if c.startswith("detected_at_rst_")}
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    for grid, rows in summary.groupby("grid"):
        row = rows.sort_values("n_robots").iloc[-1]
        xs = sorted(columns.values())
        ys = [row[c] for c, _ in sorted(columns.items(), key=lambda kv: kv[1])]
        ax.plot(xs, ys, marker="o", label=f"{grid} ({int(row['n_robots'])} robots)")
    ax.set_xlabel("target sensing range r_st / a [grid spacings]")
    ax.set_ylabel("detected share of A_d [share of the area]")
    ax.set_title("reproduce search: coverage of the visited vertices (situation 2)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend()
    return save_figure(fig, path, dpi=130, tight=True)


def draw_area(ax: plt.Axes, trace: Trace, show_grid: bool = True) -> None:
    """Border, obstacles, grid vertices (inaccessible ones as crosses) and targets."""
    ws = trace.workspace
    if ws is not None:
        ax.add_patch(PolygonPatch(ws.bounds, closed=True, fill=False, edgecolor="black", linewidth=1.5))
        for obs in ws.obstacles:
            ax.add_patch(PolygonPatch(obs, closed=True, facecolor="0.55", edgecolor="black"))
    md = trace.metadata
    if show_grid and "grid_points" in md:
        pts = np.asarray(md["grid_points"], dtype=float)
        acc = np.asarray(md["accessible"], dtype=bool)
        ax.plot(pts[acc, 0], pts[acc, 1], ".", color="0.7", markersize=3, label="grid vertex")
        if (~acc).any():
            ax.plot(pts[~acc, 0], pts[~acc, 1], "x", color="0.8", markersize=3, label="inaccessible vertex")
    targets = np.asarray(md.get("targets", []), dtype=float).reshape(-1, 2)
    if len(targets):
        ax.plot(targets[:, 0], targets[:, 1], "*", color="crimson", markersize=12, label="targets")
    ax.set_aspect("equal")
    ax.set(xlabel="x [m]", ylabel="y [m]")
    if ws is not None:
        xmin, ymin, xmax, ymax = ws.extent
        ax.set_xlim(xmin - 0.3, xmax + 0.3)
        ax.set_ylim(ymin - 0.3, ymax + 0.3)


def plot_routes(trace: Trace, path: str | Path, robots: list[int] | None = None, title: str | None = None) -> Path:
    """Routes of ``robots`` (default all) with arrows along the moves (Figs. 5 and 6)."""
    pos = trace.positions
    robots = list(range(pos.shape[1])) if robots is None else list(robots)
    fig, ax = workspace_figure(*area_corners(trace))
    draw_area(ax, trace)
    colors = plt.cm.tab10(np.arange(pos.shape[1]) % 10)
    for r in robots:
        p = pos[:, r]
        step = np.diff(p, axis=0)
        moved = np.linalg.norm(step, axis=1) > 1e-9
        ax.quiver(p[:-1][moved, 0], p[:-1][moved, 1], step[moved, 0], step[moved, 1], angles="xy", scale_units="xy",
                  scale=1, color=colors[r], width=0.004, alpha=0.8)
        ax.plot(p[0, 0], p[0, 1], "s", color=colors[r], markersize=9, label=f"robot {r} start")
    res = trace.results
    ax.set_title(f"{run_title(trace)}\n" + (title or f"{len(robots)} route(s), search time {res.get('search_time', float('nan')):.1f} s"),
                 fontsize=9)
    handles, _ = ax.get_legend_handles_labels()
    outside_legend(ax, handles + [proxy("move (arrow along the edge)", color=colors[robots[0] if robots else 0], marker=">", ls="-", ms=5)])
    return save_figure(fit_canvas(fig), path, dpi=130)


def area_corners(trace: Trace) -> tuple[np.ndarray, np.ndarray]:
    """Lower-left and upper-right corners of the searched area (else of the positions)."""
    if trace.workspace is not None:
        x0, y0, x1, y1 = trace.workspace.extent
        return np.array([x0, y0]), np.array([x1, y1])
    xy = trace.positions.reshape(-1, 2)
    return xy.min(axis=0), xy.max(axis=0)


def plot_trace(trace: Trace, path: str | Path) -> Path:
    """The routes of every robot of a run over the area and its grid (Fig. 5)."""
    return plot_routes(trace, path)


def animate_trace(trace: Trace, path: str | Path, fps: int = 6, max_frames: int = 150) -> Path:
    """GIF of a search run: robots (failed ones crossed out), their trails and the visited vertices."""
    pos = trace.positions
    times = trace.arrays["time"][:, 0, 0] if "time" in trace.arrays else np.arange(len(pos), dtype=float)
    fig, ax = workspace_figure(*area_corners(trace))
    draw_area(ax, trace)
    colors = plt.cm.tab10(np.arange(pos.shape[1]) % 10)
    handles, _ = ax.get_legend_handles_labels()
    handles += [proxy("robot (one colour each)", color=colors[0], marker="o", ms=8), proxy("trail", color=colors[0], ls="-"),
                proxy("visited vertex", color="tab:green", marker="o", ms=4)]
    trails = [ax.plot([], [], "-", color=c, linewidth=1.2, alpha=0.7)[0] for c in colors]
    dots = ax.scatter(pos[0, :, 0], pos[0, :, 1], s=60, c=colors, edgecolors="black", zorder=5)
    seen = ax.scatter([], [], s=14, c="tab:green", alpha=0.5, zorder=2)
    title = FrameTitle(ax, run_title(trace))
    visited_sets = _visited_until(trace)
    failed_at = {e["robot"]: e["step"] for e in trace.events if e["kind"] == "failure"}
    dead = ax.scatter([], [], s=120, marker="x", c="black", zorder=6)
    if failed_at:
        handles.append(proxy("failed robot", color="k", marker="x", ms=9))
    outside_legend(ax, handles)

    def update(k: int):
        for r, line in enumerate(trails):
            line.set_data(pos[: k + 1, r, 0], pos[: k + 1, r, 1])
        dots.set_offsets(pos[k])
        down = [r for r, step in failed_at.items() if step <= k]
        dead.set_offsets(pos[k, down] if down else np.empty((0, 2)))
        seen.set_offsets(visited_sets(k))
        return [*trails, dots, seen, dead, title.show(f"step {k}, t = {times[k]:.1f} s")]

    frames = frame_indices(len(pos), max_frames)
    update(frames[0])
    fit_canvas(fig)  # to the area, the legend and the first frame's title
    return save_gif(fig, update, frames, path, fps=fps, blit=True)


def _visited_until(trace: Trace):
    """``k ↦ (m, 2)`` coordinates of the vertices visited by step ``k``."""
    pos = trace.positions.reshape(len(trace.positions), -1, 2)

    def at(k: int) -> np.ndarray:
        pts = pos[: k + 1].reshape(-1, 2)
        return np.unique(np.round(pts, 9), axis=0)

    return at
