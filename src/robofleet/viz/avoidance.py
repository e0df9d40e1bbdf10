"""Figures and animations of avoidance traces (reads traces only)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, Ellipse, Polygon as PolygonPatch  # noqa: E402
from shapely.geometry import Polygon, box  # noqa: E402

from ..core.trace import Trace  # noqa: E402
from .animation import frame_indices, save_figure, save_gif  # noqa: E402


def draw_workspace(ax, trace: Trace) -> None:
    """Bounds, obstacles and goals."""
    ws = trace.workspace
    if ws is not None:
        ax.add_patch(PolygonPatch(ws.bounds, closed=True, fill=False, lw=1.2, color="k"))
        for verts in ws.obstacles:
            ax.add_patch(PolygonPatch(verts, closed=True, color="0.35"))
        x0, y0, x1, y1 = ws.extent
        pad = 0.03 * max(x1 - x0, y1 - y0)
        ax.set_xlim(x0 - pad, x1 + pad)
        ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_aspect("equal")


def plot_paths(trace: Trace, path: str | Path | None = None, ax=None):
    """Static figure: every robot's true path, start (○) and goal (×)."""
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(6, 6))
    draw_workspace(ax, trace)
    pos = trace.positions
    goals = np.asarray(trace.metadata["goals"])
    colors = plt.cm.tab20(np.linspace(0, 1, pos.shape[1], endpoint=False))
    for i in range(pos.shape[1]):
        ax.plot(pos[:, i, 0], pos[:, i, 1], color=colors[i], lw=1)
        ax.plot(*pos[0, i], "o", color=colors[i], ms=4)
        ax.plot(*goals[i], "x", color=colors[i], ms=6)
    summary = trace.summary()
    ax.set_title(f"{trace.metadata.get('method', '')}: success={summary['success']}, collisions={summary['collisions']}")
    if own and path is not None:
        fig.savefig(path, dpi=120, bbox_inches="tight")
        plt.close(fig)
    return ax


def cell_polygon(A: np.ndarray, b: np.ndarray, clip) -> Polygon:
    """Polygon of ``{p : A p ≤ b}`` clipped to ``clip`` (a shapely polygon)."""
    poly = clip
    for a, off in zip(A, b):
        if not np.any(a):
            continue
        # a half-plane as a large polygon: points with a·p ≤ off
        t = np.array([-a[1], a[0]])
        base = a * off
        far = 1e4
        half = Polygon([base + far * t, base - far * t, base - far * t - far * a, base + far * t - far * a])
        poly = poly.intersection(half)
        if poly.is_empty:
            break
    return poly


def animate_trace(trace: Trace, path: str | Path, fps: int = 10, max_frames: int = 150) -> Path:
    """GIF of robots (true discs), estimates, 3σ uncertainty ellipses, goals and, when the
    trace recorded them, every robot's cell."""
    pos, est = trace.positions, trace.arrays["estimates"]
    goals = np.asarray(trace.metadata["goals"])
    radius = float(trace.metadata["radius"])
    cov = np.asarray(trace.metadata.get("robot_cov", np.zeros((2, 2))))
    has_cells = "cell_A" in trace.arrays
    clip = Polygon(trace.workspace.bounds) if trace.workspace is not None else box(*pos.reshape(-1, 2).min(0), *pos.reshape(-1, 2).max(0))
    n = pos.shape[1]
    colors = plt.cm.tab20(np.linspace(0, 1, n, endpoint=False))
    w, h, ang = _ellipse(cov, 3.0)
    fig, ax = plt.subplots(figsize=(6, 6))
    dt = float(trace.metadata["dt"])

    def update(k: int):
        ax.clear()
        draw_workspace(ax, trace)
        step = min(k, len(est) - 1)
        for i in range(n):
            if has_cells:
                poly = cell_polygon(trace.arrays["cell_A"][step, i], trace.arrays["cell_b"][step, i], clip)
                if not poly.is_empty and poly.geom_type == "Polygon":
                    ax.add_patch(PolygonPatch(np.asarray(poly.exterior.coords), closed=True, fc=colors[i], alpha=0.15, ec=colors[i], lw=0.6))
            ax.plot(pos[: k + 1, i, 0], pos[: k + 1, i, 1], color=colors[i], lw=0.6, alpha=0.6)
            ax.add_patch(Circle(pos[k, i], radius, color=colors[i]))
            if len(est) and w > 0:
                ax.add_patch(Ellipse(est[step, i], w, h, angle=ang, fill=False, ec=colors[i], ls="--", lw=0.6))
            ax.plot(*goals[i], "x", color=colors[i])
        ax.set_title(f"{trace.metadata.get('method', '')}  t = {k * dt:.1f} s")

    return save_gif(fig, update, frame_indices(len(pos), max_frames), path, fps)


def _ellipse(cov: np.ndarray, k: float):
    """Width, height and angle (degrees) of the k-σ ellipse of a 2×2 covariance."""
    vals, vecs = np.linalg.eigh(cov)
    vals = np.maximum(vals, 0.0)
    angle = float(np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1])))
    return 2 * k * np.sqrt(vals[1]), 2 * k * np.sqrt(vals[0]), angle


def plot_reproduction(noise, delta, path: str | Path) -> Path:
    """Four panels: run collision rate, success and travel time against σ per method, and
    the per-step pair collision rate of B-UAVC against δ (with the bound y = δ)."""
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    for method, grp in noise.groupby("method"):
        axes[0].plot(grp["sigma"], grp["run_collided"], "o-", label=method)
        axes[1].plot(grp["sigma"], grp["success"], "o-", label=method)
        axes[2].plot(grp["sigma"], grp["mean_travel_time"], "o-", label=method)
    axes[0].set(xlabel="σ [m]", ylabel="runs with a collision", title="collisions vs noise")
    axes[1].set(xlabel="σ [m]", ylabel="success rate", title="success vs noise")
    axes[2].set(xlabel="σ [m]", ylabel="mean travel time [s]", title="travel time vs noise")
    axes[0].legend()
    d = delta["delta"].to_numpy()
    pooled = delta["pair_step_pooled"].to_numpy()
    seen = pooled > 0
    axes[3].loglog(d[seen], pooled[seen], "o", label="B-UAVC, observed per pair and step")
    axes[3].loglog(d, delta["pair_step_upper"].to_numpy(), "v-", label="95 % upper bound of the observed rate")
    axes[3].loglog(d, d, "k--", label="bound δ")
    axes[3].set(xlabel="δ", ylabel="empirical collision probability", title="chance constraint")
    axes[3].legend(fontsize=7)
    return save_figure(fig, path, tight=True)
