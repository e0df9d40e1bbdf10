"""The start and goal distance check of avoidance scenarios: numpy's cell list
(:func:`robofleet.core.geometry.close_pairs_in_cells`) finds exactly the pairs of the k-d
tree (:func:`robofleet.core.geometry.close_pairs`), and a scenario names its first
overlapping pair."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.core.errors import ScenarioError
from robofleet.core.geometry import close_pairs, close_pairs_in_cells
from robofleet.scenarios import load_scenario


def sorted_pairs(pairs: np.ndarray) -> np.ndarray:
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def random_points(rng: np.random.Generator, n: int, dim: int, radius: float, kind: int) -> np.ndarray:
    """Uniform points; lattice points ``radius`` apart (distances exactly at the threshold);
    pairs one float step inside and at the threshold; clusters of equal points far from the
    origin; a line of points (one column of cubes)."""
    if kind == 0:
        return rng.uniform(-5, 5, (n, dim))
    if kind == 1:
        return rng.integers(-4, 5, (n, dim)) * radius + rng.uniform(-1e3, 1e3)
    if kind == 2:
        pts = rng.uniform(-5, 5, (max(n, 3), dim))
        direction = rng.normal(size=dim)
        direction /= np.linalg.norm(direction)
        pts[1] = pts[0] + radius * direction
        pts[2] = pts[0] + np.nextafter(radius, 0.0) * direction
        return pts
    if kind == 3:
        centres = rng.uniform(-1e6, 1e6, (max(n // 3, 1), dim))
        return np.repeat(centres, 3, axis=0)[:n] + rng.integers(0, 2, (min(n, 3 * len(centres)), dim)) * radius
    pts = np.zeros((n, dim))
    pts[:, 1] = np.arange(n) * radius * rng.choice([0.5, 1.0, 2.0])
    return pts


@pytest.mark.parametrize("kind", range(5))
def test_the_cell_list_finds_exactly_the_pairs_of_the_k_d_tree(kind):
    rng = np.random.default_rng(20 + kind)
    for _ in range(300):
        dim, radius = int(rng.integers(2, 4)), float(rng.uniform(0.01, 2.0))
        pts = random_points(rng, int(rng.integers(0, 80)), dim, radius, kind)
        expected = sorted_pairs(close_pairs(pts, radius))
        got = close_pairs_in_cells(pts, radius)
        assert got.dtype == np.intp and got.shape[1:] == (2,)
        assert np.array_equal(got, expected), (kind, dim, radius)


def test_the_cell_list_handles_no_pairs_one_point_and_a_spread_far_beyond_the_cube_count():
    assert close_pairs_in_cells(np.zeros((0, 2)), 1.0).shape == (0, 2)
    assert close_pairs_in_cells(np.zeros((1, 3)), 1.0).shape == (0, 2)
    far = np.array([[0.0, 0.0], [1e12, 0.0], [1e12 + 1e-3, 0.0], [-1e12, 5.0]])
    assert close_pairs_in_cells(far, 1e-2).tolist() == sorted_pairs(close_pairs(far, 1e-2)).tolist() == [[1, 2]]


def circle_scenario(starts: list) -> dict:
    return {"family": "avoidance", "method": "buavc", "workspace": {"bounds": [-5, -5, 5, 5]},
            "robots": {"n": len(starts), "radius": 0.2, "v_max": 0.4, "sigma": 0.0,
                       "layout": {"kind": "explicit", "starts": starts, "goals": [[x, -4.0] for x, _ in starts]}}}


def test_a_scenario_with_several_overlaps_names_its_lowest_numbered_robot_and_the_robot_it_overlaps():
    starts = [[3.0, 3.0], [-3.0, 3.0], [0.0, 0.0], [3.1, 3.0], [0.1, 0.0]]
    with pytest.raises(ScenarioError) as caught:
        load_scenario(circle_scenario(starts))
    assert str(caught.value) == ("<mapping>: robots.layout.starts[0]: expected robots at least 2·radius = 0.4 apart, "
                                 "received '[3.0, 3.0] overlaps robot 3 at [3.1, 3.0]'")
