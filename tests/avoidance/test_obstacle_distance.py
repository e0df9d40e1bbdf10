"""The distance to the nearest obstacle, computed for blocks of obstacles at once, is exactly
the minimum of each obstacle's own polygon distance."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.core import geometry, workspace
from robofleet.core.workspace import Workspace


def random_polygon(rng, convex: bool) -> np.ndarray:
    """A star-shaped (or convex) polygon of 3–9 vertices around a random centre."""
    centre, count = rng.uniform(-5, 5, 2), int(rng.integers(3, 10))
    angles = np.sort(rng.uniform(0, 2 * np.pi, count))
    radii = np.full(count, rng.uniform(0.2, 2.0)) if convex else rng.uniform(0.1, 2.0, count)
    return centre + np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])


def one_obstacle_at_a_time(ws: Workspace, points: np.ndarray) -> np.ndarray:
    out = np.full(np.shape(points)[:-1], np.inf)
    for vertices in ws.obstacles:
        out = np.minimum(out, geometry.polygon_distance(points, vertices))
    return out


@pytest.mark.parametrize("block", [workspace.DISTANCE_BLOCK, 1, 40])
def test_blocks_of_obstacles_give_each_obstacle_s_own_distance(monkeypatch, block):
    monkeypatch.setattr(workspace, "DISTANCE_BLOCK", block)
    rng = np.random.default_rng(11)
    for trial in range(120):
        polygons = [random_polygon(rng, convex=bool(rng.integers(2))) for _ in range(int(rng.integers(1, 12)))]
        ws = Workspace.rectangle(-8, -8, 8, 8, polygons)
        shape = [(7, 2), (3, 5, 2), (2,), (0, 2), (500, 2)][trial % 5]
        points = rng.uniform(-8, 8, shape)
        points[..., :1] = np.where(rng.random(points[..., :1].shape) < 0.1, ws.obstacles[0][0, 0], points[..., :1])  # on a vertex's x
        got = ws.obstacle_distance(points)
        assert got.shape == shape[:-1]
        np.testing.assert_array_equal(got, one_obstacle_at_a_time(ws, points), err_msg=str(trial))


def test_inside_an_obstacle_is_zero_and_without_obstacles_infinite():
    ws = Workspace.rectangle(0, 0, 10, 10, [np.array([[1, 1], [3, 1], [3, 3], [1, 3]], float)])
    np.testing.assert_array_equal(ws.obstacle_distance(np.array([[2.0, 2.0], [5.0, 2.0]])), [0.0, 2.0])
    assert np.isinf(Workspace.rectangle(0, 0, 1, 1).obstacle_distance(np.array([[0.5, 0.5]]))).all()
