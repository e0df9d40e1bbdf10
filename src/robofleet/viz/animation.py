"""Headless-safe figure and animation writers shared by every family's viz module."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Callable

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402


def save_figure(fig: "plt.Figure", path: str | Path, dpi: int = 120, tight: bool = False) -> Path:
    """Write ``fig`` to ``path`` (parent folders created), close it, return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def save_gif(fig: "plt.Figure", update: Callable[[int], object], frames: Iterable[int], path: str | Path, fps: int = 10) -> Path:
    """Render ``update(frame)`` for every item of ``frames`` into a GIF at ``path``.

    ``update`` redraws the figure for one frame (it may return artists; blitting is off).
    The figure is closed afterwards.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    anim = FuncAnimation(fig, update, frames=frames, blit=False, cache_frame_data=False)
    anim.save(str(path), writer=PillowWriter(fps=fps))
    plt.close(fig)
    return path


def frame_indices(n_steps: int, max_frames: int = 150) -> list[int]:
    """At most ``max_frames`` evenly spaced step indices, always including the last."""
    if n_steps <= max_frames:
        return list(range(n_steps))
    stride = -(-n_steps // max_frames)
    idx = list(range(0, n_steps, stride))
    if idx[-1] != n_steps - 1:
        idx.append(n_steps - 1)
    return idx
