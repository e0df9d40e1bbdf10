"""Headless-safe figure and animation writers shared by every family's viz module."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.text import Text
from matplotlib.transforms import blended_transform_factory
from PIL import Image

from ..core.files import replacing
from ..core.progress import tracked
from ..core.trace import Trace
from .framing import frame_indices, method_of, run_title

PALETTE_THREADS = 2
"""Threads computing the GIF frames' palettes while the main thread draws."""


def save_figure(fig: plt.Figure, path: str | Path, dpi: int = 120, tight: bool = False) -> Path:
    """Write ``fig`` to ``path`` (parent folders created; the file replaced only once
    complete, :func:`~robofleet.core.files.replacing`), close it, return the path."""
    path = Path(path)
    if tight:
        fig.tight_layout()
    try:
        with replacing(path) as temp:
            fig.savefig(temp, dpi=dpi)
    finally:
        plt.close(fig)
    return path


def save_gif(fig: plt.Figure, update: Callable[[int], object], frames: Iterable[int], path: str | Path, fps: int = 10,
             progress: bool = True, blit: bool = False) -> Path:
    """Render ``update(frame)`` for every item of ``frames`` into a GIF at ``path``.

    ``update`` sets the figure up for one frame. Each frame is drawn once on the Agg
    canvas and written as matplotlib's ``PillowWriter`` writes it (the same bytes), without
    its second draw per frame; the frames' palettes are computed in threads while the next
    frames are drawn. With ``blit``, ``update`` returns the artists it changes (and nothing
    else may change): everything else is drawn once, and each frame redraws only those
    artists over it. A progress bar counts the rendered frames (on a terminal, unless
    ``progress`` is false). The figure is closed afterwards.
    """
    path = Path(path)
    frames = list(frames)
    render = blitted_frames if blit else drawn_frames
    with tracked(len(frames), f"rendering {path.name}", enabled=progress) as advance, \
            ThreadPoolExecutor(PALETTE_THREADS) as palettes:
        pending = []
        for image in render(fig, update, frames):
            pending.append(palettes.submit(gif_frame, image))
            advance()
        images = [future.result() for future in pending]
    write_gif(images, path, fps)
    plt.close(fig)
    return path


def drawn_frames(fig: plt.Figure, update: Callable[[int], object], frames: list[int]) -> Iterator[Image.Image]:
    """Each frame: ``update`` it, draw the whole figure once, take its pixels."""
    for frame in frames:
        update(frame)
        fig.canvas.draw()
        yield canvas_image(fig)


def blitted_frames(fig: plt.Figure, update: Callable[[int], object], frames: list[int]) -> Iterator[Image.Image]:
    """The figure without the artists ``update`` returns, drawn once; each frame restores
    it and draws those artists (in the order returned) on top."""
    moving = list(update(frames[0]) or ())
    for artist in moving:
        artist.set_animated(True)
    fig.canvas.draw()
    background = fig.canvas.copy_from_bbox(fig.bbox)
    for frame in frames:
        update(frame)
        fig.canvas.restore_region(background)
        for artist in moving:
            fig.draw_artist(artist)
        yield canvas_image(fig)


def canvas_image(fig: plt.Figure) -> Image.Image:
    """The canvas's pixels: RGB when opaque, else RGBA (as ``PillowWriter`` keeps them)."""
    image = Image.frombytes("RGBA", fig.canvas.get_width_height(), bytes(fig.canvas.buffer_rgba()))
    return image if image.getextrema()[3][0] < 255 else image.convert("RGB")


def gif_frame(image: Image.Image) -> Image.Image:
    """An RGB frame in its own adaptive palette, as Pillow's GIF writer would convert it
    (Pillow computes palettes without holding the GIL); other frames are left to the writer."""
    return image.convert("P", palette=Image.Palette.ADAPTIVE) if image.mode == "RGB" else image


def write_gif(images: list[Image.Image], path: Path, fps: int) -> None:
    """An endlessly looping GIF of ``images``, ``1000 / fps`` ms each (the file replaced
    only once complete, :func:`~robofleet.core.files.replacing`)."""
    with replacing(path) as temp:
        images[0].save(temp, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)


def proxy(label: str, *, color: Any = "k", marker: str = "", ls: str = "", ms: float = 7, mfc: Any = None, lw: float = 1.5) -> Line2D:
    """A legend entry for something drawn without a label (patches, per-frame artists)."""
    return Line2D([], [], color=color, marker=marker or None, ls=ls or "none", ms=ms, lw=lw,
                  mfc=color if mfc is None else mfc, label=label)


AXES_INCHES = 5.0
"""The longer side of the axes that shows a run's workspace, in inches."""
MIN_AXES_INCHES = 1.5
"""The shorter side of those axes at least (a corridor-like workspace stays readable)."""


class FrameTitle:
    """An animation's two-line title: a heading that stays (the run), drawn once with the
    background, over a line that changes every frame (time, counts).

    The heading is the axes title with an empty second line; the changing line is a text
    of its own at that second line's baseline, centred as the title's lines are, so a
    frame looks as with the whole title redrawn, while blitting redraws only the short line.
    """

    def __init__(self, ax: plt.Axes, heading: str, fontsize: float = 9):
        self.title = ax.set_title(f"{heading}\n ", fontsize=fontsize)
        self.line = ax.text(*self.title.get_position(), "", fontsize=fontsize, ha="center", va="baseline",
                            transform=self.title.get_transform())

    def show(self, text: str) -> Text:
        """Set the changing line to ``text`` (at the title's current place); return its artist."""
        self.line.set_position(self.title.get_position())
        self.line.set_text(text)
        return self.line


def workspace_figure(lo: Any, hi: Any, longest: float = AXES_INCHES) -> tuple[plt.Figure, plt.Axes]:
    """A figure with one axes shaped like the drawn area ``[lo, hi]`` (x, y corners): its
    longer side ``longest`` inches. Draw into it, then :func:`fit_canvas` sizes the canvas
    to what was drawn."""
    span = np.maximum(np.asarray(hi, float)[:2] - np.asarray(lo, float)[:2], 1e-9)
    aspect = float(span[1] / span[0])
    width, height = (longest, longest * aspect) if aspect <= 1 else (longest / aspect, longest)
    width, height = max(width, MIN_AXES_INCHES), max(height, MIN_AXES_INCHES)
    margin = 2.0  # inches around the axes while drawing; fit_canvas trims what is not used
    fig = plt.figure(figsize=(width + 2 * margin, height + 2 * margin))
    ax = fig.add_axes((margin / (width + 2 * margin), margin / (height + 2 * margin),
                       width / (width + 2 * margin), height / (height + 2 * margin)))
    return fig, ax


def fit_canvas(fig: plt.Figure, pad: float = 0.1) -> plt.Figure:
    """Size the canvas to everything drawn on it — axes, labels, titles, legends outside the
    axes, colour bars — plus ``pad`` inches, keeping every axes' size in inches.

    An equal-aspect axes then fills the canvas but for its labels, title and legend: the
    canvas takes the workspace's aspect (plus the legend's column), with no blank bands,
    and no legend reaches past an edge. Animations fit their first frame before rendering."""
    fig.draw_without_rendering()  # the layout of a draw (ticks, legends, aspect), no pixels
    box = fig.get_tightbbox(fig.canvas.get_renderer())  # inches
    width, height = fig.get_size_inches()
    new_width, new_height = box.width + 2 * pad, box.height + 2 * pad
    dx, dy = box.x0 - pad, box.y0 - pad
    for ax in fig.axes:
        p = ax.get_position()
        ax.set_position(((p.x0 * width - dx) / new_width, (p.y0 * height - dy) / new_height,
                         p.width * width / new_width, p.height * height / new_height))
    fig.set_size_inches(new_width, new_height)
    return fig


def outside_legend(ax: plt.Axes, handles: list, fontsize: float = 7) -> None:
    """The legend of ``handles`` to the right of the axes (it never hides what is drawn)."""
    ax.legend(handles=handles, fontsize=fontsize, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def visible_legend(ax: plt.Axes, **kwargs: Any) -> None:
    """A legend of the labelled artists that show data (an empty series gets no entry)."""
    handles, labels = [], []
    for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
        data = getattr(handle, "get_xdata", None)
        if data is not None and len(data()) == 0:
            continue
        handles.append(handle)
        labels.append(label)
    if handles:
        ax.legend(handles, labels, **kwargs)


def mark_zero_rates(ax: plt.Axes, x: Any, upper: Any = None, *, color: Any = "C0") -> None:
    """Rates of 0 on a log axis, honestly: an open ▽ at the 95 % upper bound of the rate,
    labelled ``0 observed (upper bound …)``; without a known bound, ▽ on the lower edge of
    the axes labelled ``0 observed (no upper bound recorded)``. Nothing is drawn at an
    invented floor."""
    x = np.atleast_1d(np.asarray(x, float))
    if not len(x):
        return
    if upper is not None and len(np.atleast_1d(upper)) == len(x) and np.all(np.asarray(upper, float) > 0):
        upper = np.atleast_1d(np.asarray(upper, float))
        span = f"{upper.min():.1e}" + (f"–{upper.max():.1e}" if upper.max() > upper.min() else "")
        ax.plot(x, upper, "v", mfc="white", mec=color, ms=8, ls="none", label=f"0 observed (upper bound {span})")
        return
    edge = blended_transform_factory(ax.transData, ax.transAxes)
    ax.plot(x, np.full(len(x), 0.03), "v", mfc="white", mec=color, ms=8, ls="none", transform=edge, clip_on=False,
            label="0 observed (no upper bound recorded)")
