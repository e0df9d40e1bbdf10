"""The shipped dense crowd swap (``avoidance/crowd_swap``) and its ``halves`` layout."""

from __future__ import annotations

import numpy as np
import pytest

import robofleet
from robofleet.avoidance.placement import halves_points
from robofleet.avoidance.layout import initial_layout
from robofleet.avoidance.spec import straight_line_budget
from robofleet.core.errors import ScenarioError
from robofleet.scenarios import catalogue


def test_the_shipped_crowd_fills_both_halves_and_swaps():
    """200 robots, 100 per half on the 1 m grid from the end walls inward, each goal the
    mirror image of its start, every start at least the grid pitch from the others and
    half a pitch inside the walls; the budget follows the straight-line rule."""
    assert "avoidance/crowd_swap" in catalogue.names()
    spec = robofleet.load_scenario("avoidance/crowd_swap")
    starts, goals, _ = initial_layout(spec, np.random.default_rng(0))
    assert len(starts) == 200 and (starts[:, 0] < 0).sum() == 100
    np.testing.assert_array_equal(goals, starts * [-1, 1])
    gaps = np.linalg.norm(starts[:, None] - starts[None], axis=-1) + np.eye(200) * 9
    assert gaps.min() >= 1.0 - 1e-12
    assert np.abs(starts[:, 0]).max() <= 12 - 0.5 + 1e-12 and np.abs(starts[:, 1]).max() <= 5 - 0.5 + 1e-12
    assert np.abs(starts[:, 0]).min() >= 12 - 10 + 0.5 - 1e-12  # the 10 outer columns of each half
    assert spec.max_steps == straight_line_budget(spec)


def test_a_shortened_crowd_swap_crosses_without_contact():
    """20 robots of the shipped scenario in a room cut to 8 m (the two columns meet after
    about 9 s): no robot–robot, robot–obstacle or robot–wall contact on true positions,
    and the crowds do cross."""
    overrides = {"robots.n": 20, "workspace.bounds": [-4, -5, 4, 5], "robots.layout.box": [-4, -5, 4, 5], "max_steps": 250}
    spec = robofleet.load_scenario("avoidance/crowd_swap", overrides)
    trace = robofleet.simulate(spec, seed=0)
    positions = trace.arrays["positions"]
    assert trace.results["collisions"] == 0 and trace.results["obstacle_collisions"] == 0
    assert np.all(spec.workspace.build().boundary_distance(positions) >= spec.robots.radius)
    crossed = np.sign(positions[-1, :, 0]) != np.sign(positions[0, :, 0])
    assert crossed.mean() >= 0.5


def test_halves_fill_from_the_end_walls_and_mirror():
    starts, goals = halves_points(7, (0, 0, 8, 2), 1.0)
    assert starts.tolist() == [[0.5, 0.5], [7.5, 0.5], [0.5, 1.5], [7.5, 1.5], [1.5, 0.5], [6.5, 0.5], [1.5, 1.5]]
    np.testing.assert_array_equal(goals, starts * [-1, 1] + [8, 0])


@pytest.mark.parametrize("overrides, field, expected", [
    ({"robots.n": 300}, "layout.box", "room for 300 robots at spacing 1.0 (each half holds 120)"),
    ({"robots.layout.box": None}, "box", "[xmin, ymin, xmax, ymax] with min < max for a halves layout"),
    ({"robots.layout.box": [4, -5, -4, 5]}, "box", "[xmin, ymin, xmax, ymax] with min < max for a halves layout"),
])
def test_a_crowd_that_does_not_fit_is_refused_in_one_line(overrides, field, expected):
    with pytest.raises(ScenarioError) as err:
        robofleet.load_scenario("avoidance/crowd_swap", overrides)
    message = str(err.value)
    assert field in message and expected in message and "\n" not in message
