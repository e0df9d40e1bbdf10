"""``save_gif`` writes what matplotlib's ``PillowWriter`` writes (the same bytes), whether
it redraws the whole figure or, with ``blit``, only the artists a frame changes."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.patches import Circle
from PIL import Image

from robofleet.viz.animation import save_gif

FRAMES = [0, 1, 2, 5]


def small_scene():
    """A figure with static layers (line, legend) and per-frame artists (disc, title)."""
    fig, ax = plt.subplots(figsize=(3, 2), dpi=60)
    ax.plot([0, 1], [0, 1], ":", label="path")
    ax.set(xlim=(-0.5, 1.5), ylim=(-0.5, 1.5))
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.subplots_adjust(right=0.6)
    disc = ax.add_patch(Circle((0, 0), 0.2, color="tab:blue", zorder=3))
    title = ax.set_title("", fontsize=8)

    def update(t):
        disc.center = (0.2 * t, 0.1 * t)
        disc.set_color("tab:green" if t == FRAMES[-1] else "tab:blue")
        title.set_text(f"t = {t}")
        return [disc, title]

    return fig, update


def pillow_writer_gif(path):
    fig, update = small_scene()
    FuncAnimation(fig, update, frames=FRAMES, blit=False, cache_frame_data=False).save(str(path), writer=PillowWriter(fps=5))
    plt.close(fig)
    return path.read_bytes()


@pytest.mark.parametrize("blit", [False, True])
def test_save_gif_writes_the_bytes_of_matplotlibs_pillow_writer(tmp_path, blit):
    fig, update = small_scene()
    out = save_gif(fig, update, FRAMES, tmp_path / "saved.gif", fps=5, progress=False, blit=blit)
    assert out.read_bytes() == pillow_writer_gif(tmp_path / "reference.gif")
    assert not plt.fignum_exists(fig.number)  # closed


def test_save_gif_frames_show_the_moving_artists(tmp_path):
    fig, update = small_scene()
    gif = Image.open(save_gif(fig, update, FRAMES, tmp_path / "moving.gif", progress=False, blit=True))
    assert gif.n_frames == len(FRAMES)
    first = np.asarray(gif.convert("RGB"), int)
    gif.seek(len(FRAMES) - 1)
    last = np.asarray(gif.convert("RGB"), int)
    assert np.abs(first - last).max() > 100  # the disc moved and turned green
