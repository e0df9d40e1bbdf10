"""Plots and animations of the robot-model B-UAVC runs (reads traces and tables only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .animation import frame_indices, plt, save_gif

METHOD_STYLE = {"buavc": ("B-UAVC", "C0", "o"), "bvc": ("BVC", "C1", "s"), "bvc_inflated": ("BVC inflated", "C2", "^"), "orca": ("ORCA", "C3", "D")}


def plot_models(noise, delta, out_dir) -> list[Path]:
    """Per model: share of runs with a collision and success rate against σ; and the
    per-step pair collision rate of B-UAVC against δ. Returns the PNG paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    models = list(dict.fromkeys(noise["model"]))
    fig, axes = plt.subplots(2, len(models), figsize=(3.2 * len(models), 5.6), squeeze=False)
    for col, model in enumerate(models):
        sub = noise[noise["model"] == model]
        for method, grp in sub.groupby("method"):
            label, colour, marker = METHOD_STYLE.get(method, (method, "k", "x"))
            grp = grp.sort_values("sigma")
            axes[0, col].plot(grp["sigma"], 100 * grp["run_collided"], marker=marker, color=colour, label=label)
            axes[1, col].plot(grp["sigma"], 100 * grp["success"], marker=marker, color=colour, label=label)
        axes[0, col].set_title(model.replace("_", " "))
        axes[0, col].set_ylim(-5, 105)
        axes[1, col].set_ylim(-5, 105)
        axes[1, col].set_xlabel("σ [m]")
    axes[0, 0].set_ylabel("runs with a collision [%]")
    axes[1, 0].set_ylabel("success [%]")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    paths = [out_dir / "models_noise.png"]
    fig.savefig(paths[0], dpi=120)
    plt.close(fig)
    if len(delta):
        fig, ax = plt.subplots(figsize=(4.5, 3.6))
        for model, grp in delta.groupby("model"):
            grp = grp.sort_values("delta")
            ax.plot(grp["delta"], np.maximum(grp["pair_step_rate"], 1e-7), marker="o", label=model.replace("_", " "))
        d = np.array(sorted(delta["delta"].unique()))
        ax.plot(d, d, "k--", label="bound δ")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("δ")
        ax.set_ylabel("pair collision rate per step")
        ax.legend(fontsize=7)
        fig.tight_layout()
        paths.append(out_dir / "models_delta.png")
        fig.savefig(paths[-1], dpi=120)
        plt.close(fig)
    return paths


def animate_run(trace, path, max_frames: int = 120, fps: int = 10) -> Path:
    """GIF of a run: 2D — discs with headings, cells and goals; 3D — top view with the
    height as colour, boxes as their footprints."""
    pos = trace.positions
    md = trace.metadata
    r = float(md["radius"])
    goals = np.asarray(md["goals"], float)
    three_d = pos.shape[2] == 3
    fig, ax = plt.subplots(figsize=(5.2, 5.0))
    frames = frame_indices(len(pos), max_frames)
    lo, hi = _extent(trace)
    heads = trace.arrays.get("headings")
    cells_A, cells_b = trace.arrays.get("cell_A"), trace.arrays.get("cell_b")
    if three_d:
        zmin, zmax = (md["bounds3d"][2], md["bounds3d"][5]) if md.get("bounds3d") else (pos[..., 2].min(), pos[..., 2].max())
        norm = plt.Normalize(zmin, zmax)
        sm = plt.cm.ScalarMappable(norm=norm, cmap="viridis")
        fig.colorbar(sm, ax=ax, label="height z [m]", shrink=0.8)

    def update(k):
        ax.clear()
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        _draw_static(ax, trace)
        ax.plot(goals[:, 0], goals[:, 1], "x", color="0.4", ms=6)
        trail = pos[max(0, k - 40): k + 1]
        for i in range(pos.shape[1]):
            ax.plot(trail[:, i, 0], trail[:, i, 1], "-", lw=0.8, color="0.6")
        colours = plt.cm.viridis(norm(pos[k, :, 2])) if three_d else [f"C{i % 10}" for i in range(pos.shape[1])]
        for i in range(pos.shape[1]):
            ax.add_patch(plt.Circle(pos[k, i, :2], r, color=colours[i], alpha=0.85))
            if heads is not None and np.isfinite(heads[k, i]):
                ax.arrow(pos[k, i, 0], pos[k, i, 1], 1.8 * r * np.cos(heads[k, i]), 1.8 * r * np.sin(heads[k, i]), head_width=0.08, color="k", lw=0.8)
        if cells_A is not None and k < len(cells_A):
            _draw_cells(ax, cells_A[k], cells_b[k], lo, hi)
        ax.set_title(f"{md.get('scenario') or ''} · {md.get('method')} · t = {k * float(md['dt']):.1f} s", fontsize=9)
        return []

    return save_gif(fig, update, frames, path, fps=fps)


def _extent(trace):
    md = trace.metadata
    if md.get("bounds3d"):
        b = md["bounds3d"]
        return np.array([b[0], b[1]]), np.array([b[3], b[4]])
    if trace.workspace is not None:
        x0, y0, x1, y1 = trace.workspace.extent
        return np.array([x0, y0]), np.array([x1, y1])
    p = trace.positions
    return p[..., :2].min(axis=(0, 1)) - 1, p[..., :2].max(axis=(0, 1)) + 1


def _draw_static(ax, trace):
    if trace.workspace is not None:
        for obstacle in trace.workspace.obstacles:
            ax.add_patch(plt.Polygon(obstacle, color="0.3"))
    for box in trace.metadata.get("boxes") or []:
        c, s, yaw = np.array(box["center"]), np.array(box["size"]), box["yaw"]
        corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * 0.5 * s[:2]
        rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        ax.add_patch(plt.Polygon(corners @ rot.T + c[:2], color="0.3", alpha=0.8))


def _draw_cells(ax, A, b, lo, hi):
    """Each robot's cell polygon (clipped to the view), by half-plane clipping of the view box."""
    for i in range(A.shape[0]):
        poly = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]], float)
        for a, beta in zip(A[i], b[i]):
            if not np.any(a):
                continue
            poly = _clip(poly, a, beta)
            if len(poly) == 0:
                break
        if len(poly) >= 3:
            ax.add_patch(plt.Polygon(poly, fill=False, lw=0.7, ec=f"C{i % 10}"))


def _clip(poly, a, beta):
    """Sutherland–Hodgman clip of a convex polygon by ``a·p ≤ β``."""
    out = []
    for p, q in zip(poly, np.roll(poly, -1, axis=0)):
        fp, fq = a @ p - beta, a @ q - beta
        if fp <= 0:
            out.append(p)
        if fp * fq < 0:
            out.append(p + (q - p) * fp / (fp - fq))
    return np.array(out)
