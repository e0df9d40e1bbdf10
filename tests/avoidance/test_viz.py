"""``robofleet.viz.avoidance``: figures of every kind of avoidance trace and of the
reproductions (drawn from traces and tables only)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

import robofleet
from robofleet.core.trace import Trace
from robofleet.viz import avoidance as viz

SCENARIOS = {  # shipped scenario: what its trace exercises
    "avoidance/circle_swap": "2-D single integrators, cells and 3σ ellipses",
    "avoidance/three_boxes": "2-D with uncertain obstacles",
    "avoidance/double_integrator": "2-D double integrators among boxes",
    "avoidance/diff_drive": "2-D unicycles with headings",
    "avoidance/quadrotors_3d": "3-D quadrotors, yawed boxes",
    "avoidance/heterogeneous": "3-D ground and air team",
}
STEPS = 4


@pytest.fixture(scope="module")
def traces() -> dict[str, Trace]:
    """A short run of every shipped scenario kind."""
    return {name: robofleet.simulate(robofleet.load_scenario(name, {"max_steps": STEPS}), seed=3) for name in SCENARIOS}


def gif_frames(path: Path) -> int:
    """Frames in a GIF file."""
    with Image.open(path) as image:
        return image.n_frames


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_plot_and_animation_of_every_trace_kind(traces, name, tmp_path):
    trace = traces[name]
    png = viz.plot_trace(trace, tmp_path / "plot.png")
    gif = viz.animate_trace(trace, tmp_path / "anim.gif")
    assert png == tmp_path / "plot.png" and png.stat().st_size > 0
    assert gif == tmp_path / "anim.gif" and gif_frames(gif) == len(trace.positions)


def test_a_saved_and_loaded_trace_draws_the_same_way(traces, tmp_path):
    loaded = Trace.load(traces["avoidance/diff_drive"].save(tmp_path / "run"))
    assert viz.plot_trace(loaded, tmp_path / "plot.png").stat().st_size > 0
    assert gif_frames(viz.animate_trace(loaded, tmp_path / "anim.gif", max_frames=3)) == 3


def test_long_runs_are_animated_with_at_most_max_frames(traces, tmp_path):
    assert gif_frames(viz.animate_trace(traces["avoidance/circle_swap"], tmp_path / "a.gif", max_frames=2)) <= 3


def test_cell_polygon_clips_by_each_half_plane_and_skips_padding():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    A = np.array([[1.0, 0.0], [0.0, 0.0], [-1.0, -1.0]])
    b = np.array([0.5, 1.0, -0.25])
    cell = viz.cell_polygon(A, b, square)
    x, y = cell[:, 0], cell[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    assert np.isclose(area, 0.5 - 0.25**2 / 2)
    assert (A[[0, 2]] @ cell.T <= b[[0, 2], None] + 1e-12).all()
    assert len(viz.cell_polygon(np.array([[1.0, 0.0]]), np.array([-1.0]), square)) == 0


def test_three_sigma_ellipse_axes_follow_the_covariance():
    width, height, angle = viz.uncertainty_ellipse(np.diag([0.04, 0.01]), 3.0)
    assert np.isclose(width, 1.2) and np.isclose(height, 0.6) and np.isclose(abs(angle) % 180, 0.0)


def test_reproduction_figures_from_tables(tmp_path):
    noise = pd.DataFrame({"method": ["buavc", "buavc", "bvc", "bvc"], "sigma": [0.05, 0.1, 0.05, 0.1],
                          "run_collided": [0.0, 0.0, 0.5, 1.0], "success": [1.0, 0.5, 0.5, 0.0],
                          "mean_travel_time": [16.0, 19.0, 15.0, 16.5]})
    delta = pd.DataFrame({"delta": [0.01, 0.1], "pair_step_pooled": [0.0, 1e-4], "pair_step_upper": [4e-5, 3e-4]})
    assert viz.plot_buavc_comparison(noise, delta, tmp_path / "c.png").stat().st_size > 0
    models = noise.assign(model=["diff_drive", "diff_drive", "quadrotor", "quadrotor"])
    assert viz.plot_models_noise(models, tmp_path / "n.png").stat().st_size > 0
    rates = pd.DataFrame({"model": ["diff_drive"] * 2, "delta": [0.01, 0.1], "pair_step_rate": [0.0, 2e-4]})
    assert viz.plot_models_delta(rates, tmp_path / "d.png").stat().st_size > 0


def test_viz_imports_only_core_and_its_own_helpers():
    tree = ast.parse(Path(viz.__file__).read_text())
    relative = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.level}
    absolute = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert relative <= {"core.trace", "core.workspace", "animation", "avoidance_geometry"}
    assert not any(name.startswith("robofleet") for name in absolute)
