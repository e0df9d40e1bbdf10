"""Estimates on an obstacle's boundary (a vertex, an edge) or just inside it: the obstacle's
plane is the face the estimate lies on, so the filtered velocity heads out of the obstacle
(and no error names an argument the caller never passed)."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.avoidance import ObstacleSet, RobotSafetyFilter, SafetyFilter, obstacle_planes
from robofleet.core import geometry

pytestmark = pytest.mark.filterwarnings("error")
DT, V_MAX = 0.1, 0.4


def random_convex_polygon(rng):
    """A random convex polygon (hull of random points, counter-clockwise) around the origin."""
    from scipy.spatial import ConvexHull

    pts = rng.normal(0.0, 1.0, (12, 2)) * rng.uniform(0.3, 1.5, 2)
    return pts[ConvexHull(pts).vertices]


def outward_gap(points, polygon):
    """Largest signed distance beyond the faces of a convex counter-clockwise polygon
    (< 0 inside, 0 on the boundary, > 0 outside)."""
    start, end = geometry.polygon_edges(polygon)
    edge = end - start
    normal = np.stack([edge[:, 1], -edge[:, 0]], axis=1) / np.linalg.norm(edge, axis=1)[:, None]
    return np.max(np.einsum("kd,...kd->...k", normal, np.asarray(points)[..., None, :] - start), axis=-1)


def boundary_points(rng, polygon, count):
    """Every vertex, every edge's midpoint, random edge points, and points 1e-12 and 1e-3
    inside (towards the centroid)."""
    start, end = geometry.polygon_edges(polygon)
    pick = rng.integers(0, len(polygon), count)
    on_edges = start[pick] + rng.uniform(0, 1, count)[:, None] * (end[pick] - start[pick])
    surface = np.concatenate([polygon, 0.5 * (start + end), on_edges])
    centre = polygon.mean(axis=0)
    inward = (centre - surface) / np.linalg.norm(centre - surface, axis=1, keepdims=True)
    return np.concatenate([surface, surface + 1e-12 * inward, surface + 1e-3 * inward])


def assert_heads_out(point, velocity, polygon):
    assert np.all(np.isfinite(velocity)) and np.linalg.norm(velocity) <= V_MAX * (1 + 1e-12)
    before, after = outward_gap(point, polygon), outward_gap(point + velocity * DT, polygon)
    assert after > before  # heads out
    if before > -V_MAX * DT / 2:
        assert after > 0  # and a step gets out from the boundary or just inside


@pytest.mark.parametrize("obstacle_cov", [None, 0.05**2 * np.eye(2)])
@pytest.mark.parametrize("cov", [np.zeros((2, 2)), np.diag([0.05, 0.02]) ** 2])
def test_a_square_s_vertices_and_edges_through_both_filters(cov, obstacle_cov):
    box = geometry.box_vertices((0.0, 0.0), (1.0, 1.0))
    fleet = SafetyFilter.create(1, radius=0.2, dt=DT, v_max=V_MAX, obstacles=[box], obstacle_cov=obstacle_cov)
    robot = RobotSafetyFilter.create(radius=0.2, dt=DT, v_max=V_MAX, obstacles=[box], obstacle_cov=obstacle_cov, deadlock=None)
    for q in [[-0.5, -0.5], [0.5, 0.5], [0.5, -0.5], [0.0, -0.5], [0.5, 0.2], [-0.5, 0.0], [0.49, 0.3], [0.0, 0.0]]:
        q = np.asarray(q, float)
        for desired in (-q, np.zeros(2), np.array([0.3, 0.0]), np.array([0.0, -0.3])):
            result = fleet.filter(q[None], cov, desired[None])
            assert_heads_out(q, result.velocity[0], box)
            alone = robot.filter(q, cov, desired)
            np.testing.assert_allclose(alone.velocity[0], result.velocity[0], atol=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_random_boundary_points_of_random_polygons_head_out(seed):
    rng = np.random.default_rng(seed)
    polygon = random_convex_polygon(rng)
    shift = rng.normal(0.0, 0.05, 2)  # the obstacle's estimated displacement puts the estimate on its boundary
    f = SafetyFilter.create(1, radius=rng.uniform(0.05, 0.4), dt=DT, v_max=V_MAX, obstacles=[polygon - shift],
                            obstacle_cov=None if seed % 2 else 0.03**2 * np.eye(2))
    for q in boundary_points(rng, polygon, 40):
        desired = rng.normal(0.0, 0.4, 2) if rng.uniform() < 0.5 else polygon.mean(axis=0) - q
        result = f.filter(q[None], np.diag(rng.uniform(0, 0.05, 2) ** 2), desired[None], obstacle_offsets=shift[None])
        assert_heads_out(q, result.velocity[0], polygon)


def test_boundary_planes_keep_the_shadow_on_the_far_side():
    """Any estimate on the boundary gets a finite unit normal and a plane beyond which the
    whole ε-shadow lies (the offset is the grown polygon's support)."""
    rng = np.random.default_rng(3)
    polygon = random_convex_polygon(rng)
    cov = np.array([[0.02, 0.005], [0.005, 0.01]])
    obstacles = ObstacleSet.build([polygon], cov[None], 0.05)
    q = boundary_points(rng, polygon, 30)
    a, b = obstacle_planes(q, obstacles, np.zeros(len(q), int))
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0, atol=1e-12)
    theta = np.linspace(0, 2 * np.pi, 361)
    ring = obstacles.shadow_radius[0] * np.stack([np.cos(theta), np.sin(theta)], 1) @ np.linalg.cholesky(cov).T
    shadow = (polygon[:, None] + ring[None]).reshape(-1, 2)
    assert np.all(shadow @ a.T >= b - 1e-9)
