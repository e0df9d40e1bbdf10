"""``save_gif`` writes what matplotlib's ``PillowWriter`` writes (the same bytes), whether
it redraws the whole figure or, with ``blit``, only the artists a frame changes."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.patches import Circle
from PIL import Image

from robofleet.viz.animation import FrameTitle, save_gif

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



def title_pixels(line: str, with_frame_title: bool) -> np.ndarray:
    """A small figure's pixels with the heading over ``line``: as a :class:`FrameTitle`, or
    as one two-line axes title."""
    fig, ax = plt.subplots(figsize=(4, 3), dpi=60)
    ax.plot([0, 1], [0, 1])
    if with_frame_title:
        FrameTitle(ax, HEADING, fontsize=8).show(line)
    else:
        ax.set_title(f"{HEADING}\n{line}", fontsize=8)
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)
    plt.close(fig)
    return image


HEADING = "scene · method · seed 3"


@pytest.mark.parametrize("line", ["t = 1.5 s · waiting: 2", "step 40, t = 12.0 s", "t = 30"])
def test_a_frame_title_draws_the_pixels_of_the_whole_two_line_title(line):
    """The heading drawn once and the changing line drawn on its own look as the title
    with both lines redrawn (each frame of a blitted animation draws only the line)."""
    assert np.array_equal(title_pixels(line, True), title_pixels(line, False))


def test_under_a_wider_line_the_heading_moves_by_less_than_a_pixel():
    """A line wider than the heading: the line's pixels are the same, and the heading's ink
    is centred within a pixel of where the two-line title puts it (antialiasing differs)."""
    line = "a line much longer than the heading above it, at every frame"
    frame_title, whole = title_pixels(line, True), title_pixels(line, False)
    ink = [255 * 3 - image.sum(axis=-1) for image in (frame_title, whole)]
    rows = np.flatnonzero(ink[1].sum(axis=1) > 0)
    gaps = np.flatnonzero(np.diff(rows) > 1)
    heading_rows = rows[: gaps[0] + 1]  # the first run of inked rows from the top
    line_rows = slice(rows[gaps[0] + 1], rows[gaps[1]] + 1)  # the second run
    assert np.array_equal(frame_title[line_rows], whole[line_rows])
    columns = np.arange(ink[0].shape[1])
    centres = [float((i[heading_rows].sum(axis=0) * columns).sum() / i[heading_rows].sum()) for i in ink]
    assert abs(centres[0] - centres[1]) < 1.0
