"""Plots and animations of the flocking family (Gervasi & Prencipe 2001, Figs. 9-11).

Reads traces and result tables only (imports :mod:`robofleet.core` pieces and matplotlib,
never the family): ``positions`` holds the leader at index 0, ``estimated_target`` the
slots of the estimated target 𝒯^{φ_B(t)} at every sample, ``leader_heading``, ``time``,
``delta_e`` and ``delta_r`` the rest of what is drawn.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

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


def plot_delta_curves(curves: pd.DataFrame, path: str | Path) -> Path:
    """Fig. 11: Δ_e(t) (top) and Δ_r(t) (bottom) per pattern; median and 10-90 % band over seeds.

    ``curves`` has columns ``pattern, run_id, t, delta_e, delta_r, xi``.
    """
    known = ["wedge", "line", "spread", "random"]
    found = list(dict.fromkeys(curves["pattern"]))
    patterns = [p for p in known if p in found] + [p for p in found if p not in known]
    fig, axes = plt.subplots(2, len(patterns), figsize=(3.6 * len(patterns), 6.0), sharex=True, squeeze=False)
    for col, pattern in enumerate(patterns):
        g = curves[curves["pattern"] == pattern]
        for row, (key, label) in enumerate((("delta_e", "Δe"), ("delta_r", "Δr"))):
            ax = axes[row, col]
            table = g.pivot_table(index="t", columns="run_id", values=key)
            q = table.quantile([0.1, 0.5, 0.9], axis=1).T
            ax.fill_between(q.index, q[0.1], q[0.9], alpha=0.25, color="C0", lw=0, label="10-90 % of the seeds")
            ax.plot(q.index, q[0.5], color="C0", lw=1.4, label="median")
            ax.axhline(g["xi"].median(), color="k", ls="--", lw=0.8, label="ξ (median)")
            ax.set_yscale("symlog", linthresh=1.0)  # logarithmic above 1 unit, linear (0 included) below: no invented floor
            ax.set_title(f"{pattern}: {label}(t)  ({table.shape[1]} seeds)", fontsize=9)
            if row == 1:
                ax.set_xlabel("time [time units]")
            if col == 0:
                ax.set_ylabel(f"{label} [units] (symlog)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("reproduce flocking: Fig. 11, distance to the pattern over time (basic algorithm)", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def plot_trace(trace: Trace, path: str | Path, title: str | None = None) -> Path:
    """Figs. 9-10: courses of the leader (black) and followers, start (○) and end (●) positions;
    the canvas sized to the courses (:func:`~.animation.fit_canvas`)."""
    pos = trace.positions
    fig, ax = workspace_figure(pos.reshape(-1, 2).min(axis=0), pos.reshape(-1, 2).max(axis=0))
    ax.plot(pos[:, 0, 0], pos[:, 0, 1], color="k", lw=2.0, label="leader")
    for i in range(1, pos.shape[1]):
        ax.plot(pos[:, i, 0], pos[:, i, 1], lw=0.8, color=f"C{i % 10}")
    ax.scatter(pos[0, 1:, 0], pos[0, 1:, 1], facecolors="none", edgecolors="0.3", s=25, label="followers, start")
    ax.scatter(pos[-1, 1:, 0], pos[-1, 1:, 1], color="0.2", s=14, label="followers, end")
    _leader_marker(ax, pos[-1, 0], trace.arrays["leader_heading"][-1])
    ax.set_aspect("equal")
    ax.set(xlabel="x [units]", ylabel="y [units]")
    r = trace.results
    ax.set_title(title or f"{run_title(trace)}\nΔe={r['delta_e_final']:.2f}, Δr={r['delta_r_final']:.2f}, ξ={r['xi']:.2f}", fontsize=9)
    handles, _ = ax.get_legend_handles_labels()
    outside_legend(ax, handles + [proxy("follower course (one colour each)", color="C1", ls="-", lw=0.8),
                                  proxy("leader at the end (along its heading)", color="k", marker=">", ms=9)])
    return save_figure(fit_canvas(fig), path, dpi=110)


def plot_comparison(table: pd.DataFrame, path: str | Path) -> Path:
    """Bars of the comparison table: share of runs with Δe ≤ ξ and mean slot changes."""
    table = table.copy()
    table["cell"] = table["pattern"] + "/" + table["scheduler"]
    cells = list(dict.fromkeys(table["cell"]))
    algs = list(dict.fromkeys(table["algorithm"]))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    width = 0.8 / len(algs)
    for k, alg in enumerate(algs):
        sub = table[table["algorithm"] == alg].set_index("cell").reindex(cells)
        x = np.arange(len(cells)) + k * width
        axes[0].bar(x, sub["Δe ≤ ξ: share"], width, label=alg)
        axes[1].bar(x, sub["slot changes (mean)"], width, label=alg)
    for ax, label, unit in zip(axes, ("share of runs with Δe ≤ ξ at the end", "slot changes per run (mean)"),
                               ("share of runs", "slot changes per run")):
        ax.set_xticks(np.arange(len(cells)) + 0.4 - width / 2)
        ax.set_xticklabels(cells, rotation=30, fontsize=8)
        ax.set_title(label, fontsize=9)
        ax.set(xlabel="pattern / scheduler", ylabel=unit)
    axes[0].legend(fontsize=7, title="algorithm", title_fontsize=7)
    fig.suptitle("reproduce flocking: variants compared", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def animate_trace(trace: Trace, path: str | Path, fps: int = 15, max_frames: int = 150, tail: int = 60) -> Path:
    """GIF of a run: leader (triangle), followers with trails, the slots of the estimated
    target. The axes, the legend and the labels are drawn once; each frame moves only the
    trails, the markers and the title (blitted, :func:`~.animation.save_gif`)."""
    pos = trace.positions
    targets = trace.arrays["estimated_target"]
    times, heading = trace.arrays["time"], trace.arrays["leader_heading"]
    frames = frame_indices(len(pos), max_frames)
    lo, hi = pos.reshape(-1, 2).min(axis=0) - 20, pos.reshape(-1, 2).max(axis=0) + 20
    fig, ax = workspace_figure(lo, hi)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set(xlabel="x [units]", ylabel="y [units]")
    outside_legend(ax, [proxy("leader (along its heading)", color="k", marker=">", ms=9),
                        proxy("follower", color="C1", marker="o", ms=6),
                        proxy(f"trail (last {tail} samples)", color="C1", ls="-", lw=0.7),
                        proxy("slot of the estimated target", color="0.5", marker="o", mfc="none", ms=8)])
    trails = [ax.plot([], [], lw=0.7, color="k" if i == 0 else f"C{i % 10}")[0] for i in range(pos.shape[1])]
    slots = ax.scatter(targets[0, :, 0], targets[0, :, 1], facecolors="none", edgecolors="0.5", s=40)
    followers = ax.scatter(pos[0, 1:, 0], pos[0, 1:, 1], c=[f"C{i % 10}" for i in range(1, pos.shape[1])], s=18)
    leader = ax.plot([], [], markersize=11, color="k", ls="none")[0]
    title = FrameTitle(ax, run_title(trace))

    def update(k: int):
        start = max(0, k - tail)
        for i, trail in enumerate(trails):
            trail.set_data(pos[start:k + 1, i, 0], pos[start:k + 1, i, 1])
        slots.set_offsets(targets[k])
        followers.set_offsets(pos[k, 1:])
        leader.set_data([pos[k, 0, 0]], [pos[k, 0, 1]])
        leader.set_marker(leader_marker(heading[k]))
        caption = title.show(f"t = {times[k]:.0f} time units · Δe = {trace.arrays['delta_e'][k]:.1f} · "
                             f"Δr = {trace.arrays['delta_r'][k]:.1f}")
        return [*trails, slots, followers, leader, caption]

    update(frames[0])
    fit_canvas(fig)
    return save_gif(fig, update, frames, path, fps=fps, blit=True)


def leader_marker(heading: float) -> tuple:
    """The leader's triangle marker pointing along ``heading`` [rad]."""
    return (3, 0, np.degrees(heading) - 90)


def _leader_marker(ax, point, heading) -> None:
    ax.plot(point[0], point[1], marker=leader_marker(heading), markersize=11, color="k", ls="none")
