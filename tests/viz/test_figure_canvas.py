"""Figures of a run size their canvas to the workspace: the axes keep the workspace's
aspect and fill the canvas but for labels, title and the legend beside them, and the
legend lies inside the canvas; the avoidance animation draws each robot's cell in the
robot's colour, within its local box."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest

import robofleet
from robofleet.viz import avoidance, coordination, flocking, search
from robofleet.viz.animation import fit_canvas, outside_legend, workspace_figure

LABELS_INCHES = 1.3
"""Room a figure needs beside its axes for a two-line title, tick and axis labels, and the pad."""


def inches(fig, artist) -> matplotlib.transforms.Bbox:
    """Where ``artist`` lies on the canvas, in inches."""
    return artist.get_window_extent(fig.canvas.get_renderer()).transformed(fig.dpi_scale_trans.inverted())


def assert_fitted(fig, ax) -> None:
    """The legend inside the canvas, and no blank band beside the axes (the canvas has the
    axes' aspect plus the legend's column)."""
    fig.canvas.draw()
    width, height = fig.get_size_inches()
    canvas = matplotlib.transforms.Bbox.from_bounds(0, 0, width, height)
    legend = inches(fig, ax.get_legend())
    assert canvas.x0 - 1e-6 <= legend.x0 and legend.x1 <= canvas.x1 + 1e-6, (legend, canvas)
    assert canvas.y0 - 1e-6 <= legend.y0 and legend.y1 <= canvas.y1 + 1e-6, (legend, canvas)
    box = inches(fig, ax)
    columns = [inches(fig, other).height for other in fig.axes if other is not ax]  # a colour bar below
    assert height - box.height - sum(columns) <= LABELS_INCHES + 0.6 * bool(columns), (height, box.height)
    assert width - box.width - legend.width <= LABELS_INCHES, (width, box.width, legend.width)


def assert_equal_aspect(fig, ax, lo, hi, pad=0.03, margin=0.0) -> None:
    """The axes box has the aspect of the drawn area ``[lo, hi]`` grown on every side by
    ``pad`` of its longer side plus ``margin``."""
    box = inches(fig, ax)
    span = np.asarray(hi, float) - np.asarray(lo, float)
    grown = span + 2 * (pad * span.max() + margin)
    assert box.height / box.width == pytest.approx(grown[1] / grown[0], rel=0.03)


WORKSPACES = {"square": [-5, -5, 5, 5], "wide": [-12, -4, 12, 4], "tall": [-4, -12, 4, 12]}


@pytest.fixture(scope="module")
def avoidance_traces():
    """Circle swaps in a square, a wide and a tall workspace, a few steps each."""
    return {shape: robofleet.simulate(robofleet.load_scenario("avoidance/circle_swap", {
        "workspace.bounds": bounds, "robots.layout.radius": 3.5, "max_steps": 4}), seed=3) for shape, bounds in WORKSPACES.items()}


@pytest.mark.parametrize("shape", list(WORKSPACES))
def test_avoidance_figure_and_animation_take_the_workspace_aspect(avoidance_traces, shape):
    trace = avoidance_traces[shape]
    lo, hi = np.array(WORKSPACES[shape][:2]), np.array(WORKSPACES[shape][2:])
    fig = avoidance.trace_figure(trace)
    assert_equal_aspect(fig, fig.axes[0], lo, hi)
    assert_fitted(fig, fig.axes[0])
    fig, update = avoidance.animation_scene(trace)
    for k in (0, len(trace.positions) - 1):
        update(k)
        assert_equal_aspect(fig, fig.axes[0], lo, hi)
        assert_fitted(fig, fig.axes[0])


def test_each_cell_is_drawn_in_its_robots_colour_within_its_local_box(avoidance_traces):
    trace = avoidance_traces["square"]
    fig, update = avoidance.animation_scene(trace)
    update(0)
    ax = fig.axes[0]
    colours = avoidance.robot_colours(trace)
    half = float(trace.metadata["local_box"])
    estimates = trace.arrays["estimates"][0]
    cells = [p for p in ax.patches if isinstance(p, matplotlib.patches.Polygon) and p.get_fill() and 0 < p.get_facecolor()[3] < 0.5]
    assert len(cells) == trace.positions.shape[1]  # one per robot, none arrived at the start
    workspace_area = 10.0 * 10.0
    for i, colour in enumerate(colours):
        mine = [p for p in cells if np.allclose(p.get_facecolor()[:3], colour[:3])]
        assert len(mine) == 1, i
        vertices = mine[0].get_xy()
        assert np.all(np.abs(vertices - estimates[i]) <= half + 1e-9)  # inside p̂_i ± R_loc
        assert np.allclose(mine[0].get_edgecolor()[:3], colour[:3])
        x, y = vertices[:, 0], vertices[:, 1]
        assert 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) < 0.2 * workspace_area
    assert len({tuple(np.round(c[:3], 6)) for c in colours}) == len(colours)  # every robot its own colour


def test_a_three_d_animation_keeps_legend_and_colour_bar_apart():
    trace = robofleet.simulate(robofleet.load_scenario("avoidance/quadrotors_3d", {"max_steps": 2}), seed=1)
    fig, update = avoidance.animation_scene(trace)
    ax, bar = fig.axes
    assert_fitted(fig, ax)
    assert not inches(fig, ax.get_legend()).overlaps(inches(fig, bar))


def captured(monkeypatch, module, name: str) -> list:
    """Figures ``module.<name>`` (save_figure or save_gif) is given, instead of writing them."""
    figures = []

    def keep(fig, *args, **kwargs):
        figures.append(fig)
        return None

    monkeypatch.setattr(module, name, keep)
    return figures


@pytest.mark.parametrize(("module", "scenario", "overrides"), [
    (coordination, "coordination/fig2_three_robots", {"simulation.max_steps": 30}),
    (search, "search/failure_injection", {}),
    (flocking, "flocking/wedge_async", {"duration": 20}),
])
def test_every_familys_figures_are_fitted(monkeypatch, module, scenario, overrides):
    trace = robofleet.simulate(robofleet.load_scenario(scenario, overrides), seed=1)
    figures = captured(monkeypatch, module, "save_figure")
    gifs = captured(monkeypatch, module, "save_gif")
    module.plot_trace(trace, "unused.png")
    module.animate_trace(trace, "unused.gif", max_frames=3)
    for fig in [*figures, *gifs]:
        assert_fitted(fig, fig.axes[0])
    if trace.workspace is not None:
        x0, y0, x1, y1 = trace.workspace.extent
        margins = {"pad": 0.0, "margin": 0.3} if module is search else {}  # the search area is drawn with 0.3 m around it
        assert_equal_aspect(figures[0], figures[0].axes[0], (x0, y0), (x1, y1), **margins)


def test_fit_canvas_keeps_the_axes_size_and_takes_in_the_legend():
    fig, ax = workspace_figure((0, 0), (20, 5))
    ax.set(xlim=(0, 20), ylim=(0, 5), aspect="equal")
    ax.plot([0, 20], [0, 5], label="a rather long legend entry that reaches far")
    outside_legend(ax, ax.get_legend_handles_labels()[0])
    fig.canvas.draw()
    before = inches(fig, ax)
    fit_canvas(fig)
    fig.canvas.draw()
    after = inches(fig, ax)
    assert after.width == pytest.approx(before.width) and after.height == pytest.approx(before.height)
    assert_fitted(fig, ax)
