"""Figures of a rendezvous run, from the trace alone."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from robofleet.core.trace import Trace
from robofleet.viz.animation import frame_indices, run_title, save_figure, save_gif


def plot_trace(trace: Trace, path: str | Path) -> Path:
    """Every robot's path, its start hollow and its end filled."""
    positions = trace.arrays["positions"]
    fig, ax = plt.subplots(figsize=(5, 5))
    for i in range(positions.shape[1]):
        ax.plot(positions[:, i, 0], positions[:, i, 1], lw=0.8)
    ax.scatter(*positions[0].T, facecolors="none", edgecolors="k", s=20, label="start")
    ax.scatter(*positions[-1].T, c="k", s=8, label="end")
    ax.set_aspect("equal")
    ax.set_title(run_title(trace), fontsize=9)
    ax.legend(loc="upper right", fontsize=8)
    return save_figure(fig, path)


def animate_trace(trace: Trace, path: str | Path) -> Path:
    """The robots gathering, one frame per recorded step (at most 150)."""
    positions = trace.arrays["positions"]
    fig, ax = plt.subplots(figsize=(5, 5))
    low, high = positions.min(axis=(0, 1)), positions.max(axis=(0, 1))
    ax.set_xlim(low[0] - 0.5, high[0] + 0.5)
    ax.set_ylim(low[1] - 0.5, high[1] + 0.5)
    ax.set_aspect("equal")
    dots = ax.scatter(*positions[0].T, c="k", s=12)

    def update(k: int):
        dots.set_offsets(positions[k])
        ax.set_title(f"{run_title(trace)} · step {k}", fontsize=9)

    return save_gif(fig, update, frame_indices(len(positions)), path, progress=False)
