"""Cells from braking segments (segment_cells.py): closest points, maximum-margin planes,
and the lemma the braking rule's induction uses — segments that keep their distances lie
in their cells."""

import numpy as np
import pytest
from shapely.geometry import LineString, Polygon

from robofleet.avoidance.braking import braking_control, stopping_point
from robofleet.avoidance.cell import CellGeometry, Kind, build_cells
from robofleet.avoidance.cell3d import shadow_radius
from robofleet.avoidance.metrics import box_distance
from robofleet.avoidance.obstacles import ObstacleSet, wall_planes
from robofleet.avoidance.random_scenarios import random_convex_polygon
from robofleet.avoidance.segment_cells import (
    closest_points_between_segments,
    segment_box_planes,
    segment_polygon_planes,
    segment_separators,
    with_braking_segments,
)
from robofleet.dynamics import double_integrator as di


def random_segments(rng, k, d):
    """Segments with some degenerate (points) and some parallel pairs."""
    p0, p1 = rng.normal(size=(k, d)), rng.normal(size=(k, d))
    q0 = rng.normal(size=(k, d))
    q1 = q0 + np.where(rng.random((k, 1)) < 0.2, p1 - p0, rng.normal(size=(k, d)))  # parallel
    p1 = np.where(rng.random((k, 1)) < 0.15, p0, p1)  # a point
    q1 = np.where(rng.random((k, 1)) < 0.15, q0, q1)
    return p0, p1, q0, q1


@pytest.mark.parametrize("d", [2, 3])
def test_closest_points_are_closest(d):
    """The pair found lies on the segments and is no farther than any sampled pair; and
    where the segments are disjoint, the slab orthogonal to it separates them (a
    certificate that nothing is closer)."""
    rng = np.random.default_rng(d)
    p0, p1, q0, q1 = random_segments(rng, 400, d)
    cp, cq = closest_points_between_segments(p0, p1, q0, q1)
    gap = np.linalg.norm(cq - cp, axis=1)
    t = np.linspace(0, 1, 101)
    sp = p0[:, None] + t[None, :, None] * (p1 - p0)[:, None]
    sq = q0[:, None] + t[None, :, None] * (q1 - q0)[:, None]
    sampled = np.linalg.norm(sp[:, :, None] - sq[:, None], axis=-1).min(axis=(1, 2))
    assert np.all(gap <= sampled + 1e-12)
    for c, a, b in ((cp, p0, p1), (cq, q0, q1)):  # on its segment
        assert np.allclose(np.linalg.norm(c - a, axis=1) + np.linalg.norm(c - b, axis=1), np.linalg.norm(b - a, axis=1), atol=1e-9)
    a, off, sep = segment_separators(p0, p1, q0, q1)
    assert np.allclose(sep, gap)
    apart = gap > 1e-9
    for end in (p0, p1):
        assert np.all((np.sum(a * end, 1) - off)[apart] <= -0.5 * gap[apart] + 1e-9)
    for end in (q0, q1):
        assert np.all((np.sum(a * end, 1) - off)[apart] >= 0.5 * gap[apart] - 1e-9)


def polygons_and_segments(rng, k):
    polygons = [np.array(random_convex_polygon(rng, rng.uniform(-1, 1, 2), rng.uniform(0.2, 0.8))) for _ in range(5)]
    start = rng.uniform(-2, 2, (k, 2))
    end = np.where(rng.random((k, 1)) < 0.2, start, start + rng.normal(scale=0.8, size=(k, 2)))
    return polygons, start, end, rng.integers(0, len(polygons), k)


@pytest.mark.parametrize("sigma_o", [0.0, 0.05])
def test_segment_polygon_planes_are_the_maximum_margin_planes(sigma_o):
    """Against shapely: rows exist exactly where the segment misses the polygon, the shadow
    (the polygon grown by r_ε σ_o) lies beyond the plane and the nearer end of the segment
    is exactly its distance from the shadow away (no plane does better; negative inside
    the shadow, as for a point)."""
    rng = np.random.default_rng(7)
    polygons, start, end, index = polygons_and_segments(rng, 600)
    obstacles = ObstacleSet.build(polygons, np.repeat((sigma_o**2 * np.eye(2))[None], len(polygons), 0), 0.05)
    a, b, ok = segment_polygon_planes(start, end, obstacles, index)
    grow = shadow_radius(0.05, 2) * sigma_o
    shapes = [Polygon(p) for p in polygons]
    dist = np.array([shapes[o].distance(LineString([s, e]) if np.any(s != e) else LineString([s, s + 1e-15])) for s, e, o in zip(start, end, index)])
    assert np.array_equal(ok, dist > 1e-9)
    margin = np.minimum(b - np.sum(a * start, 1), b - np.sum(a * end, 1))
    assert np.allclose(margin[ok], dist[ok] - grow, atol=1e-9)
    for k in np.flatnonzero(ok):  # the (grown) polygon beyond the plane
        assert np.all(polygons[index[k]] @ a[k] >= b[k] + grow - 1e-9)


def test_segment_box_planes_are_the_maximum_margin_planes():
    """3-D: yawed boxes, segments in any direction; the margin of the nearer end equals the
    sampled distance from the segment to the box's shadow, the box lies beyond the plane."""
    rng = np.random.default_rng(3)
    k, sigma, eps = 300, 0.03, 0.05
    centers, sizes, yaws = rng.uniform(-1, 1, (4, 3)), rng.uniform(0.2, 1.0, (4, 3)), rng.uniform(0, np.pi, 4)
    start = rng.uniform(-2, 2, (k, 3))
    end = np.where(rng.random((k, 1)) < 0.2, start, start + rng.normal(scale=0.8, size=(k, 3)))
    index = rng.integers(0, 4, k)
    a, b, ok = segment_box_planes(start, end, centers, sizes, yaws, sigma, eps, index)
    t = np.linspace(0, 1, 2001)
    pts = start[:, None] + t[None, :, None] * (end - start)[:, None]
    dist = np.array([box_distance(pts[r], centers[index[r]][None], sizes[index[r]][None], yaws[index[r]][None]).min() for r in range(k)])
    grow = shadow_radius(eps, 3) * sigma
    assert np.array_equal(ok, dist > 1e-9)
    margin = np.minimum(b - np.sum(a * start, 1), b - np.sum(a * end, 1))
    assert np.all(margin[ok] <= dist[ok] - grow + 1e-9)  # no better than the distance
    assert np.all(margin[ok] >= dist[ok] - grow - 1e-6)  # and as good (sampling: 1/2000 of a segment)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    for r in np.flatnonzero(ok):
        c, s = np.cos(yaws[index[r]]), np.sin(yaws[index[r]])
        rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        corners = centers[index[r]] + (signs * 0.5 * sizes[index[r]]) @ rot.T
        assert np.all(corners @ a[r] >= b[r] + grow - 1e-9)


def separated_segments(rng, n, radius, polygons, half, at_rest):
    """``n`` random braking segments (a share ``at_rest`` of them points) at least
    ``r_i + r_j`` apart and ``r_i`` from the polygons and the walls (rejection sampling)."""
    shapes = [Polygon(p) for p in polygons]
    starts, ends = [], []
    while len(starts) < n:
        i = len(starts)
        s = rng.uniform(-half, half, 2)
        e = s + rng.normal(scale=0.4, size=2) * (rng.random() >= at_rest)
        line = LineString([s, e]) if np.any(s != e) else LineString([s, s + 1e-12])
        if np.any(np.abs([s, e]) > half - radius[i]) or any(p.distance(line) < radius[i] for p in shapes):
            continue
        if any(LineString([a, b] if np.any(a != b) else [a, a + 1e-12]).distance(line) < radius[i] + radius[k]
               for k, (a, b) in enumerate(zip(starts, ends))):
            continue
        starts.append(s), ends.append(e)
    return np.array(starts), np.array(ends)


@pytest.mark.parametrize("seed", range(12))
def test_separated_segments_lie_in_their_cells(seed):
    """The lemma of the braking rule's proof (step (a)): with Σ = Σ_o = 0, segments pairwise
    at least r_i + r_j apart, at least r_i from every obstacle and inside the walls lie in
    their cells, and every pair's two rows are reciprocal. Radii are drawn per robot."""
    rng = np.random.default_rng(seed)
    half, n = 3.0, 14
    points = seed % 2 == 1
    radius = rng.uniform(0.1, 0.3, n)
    polygons = [np.array(random_convex_polygon(rng, c, 0.5)) for c in ([-1.5, -1.5], [1.5, 0.5], [-0.5, 1.8])]
    starts, ends = separated_segments(rng, n, radius, polygons, half, 0.3 if points else 0.0)
    obstacles = ObstacleSet.build(polygons, np.zeros((len(polygons), 2, 2)), 0.0)
    geometry = CellGeometry(obstacles, *wall_planes(np.array([[-half, -half], [half, -half], [half, half], [-half, half]])))
    covs = np.zeros((n, 2, 2))
    cells = with_braking_segments(build_cells(starts, covs, radius, 1.6, geometry, 10.0), starts, ends, covs, radius, 1.6, obstacles=obstacles)
    for points in (starts, ends):
        slack = np.einsum("nmd,nd->nm", cells.A, points) - cells.b
        assert np.all((slack <= 1e-9) | ~cells.valid)
    robot = cells.valid & (cells.kind == Kind.ROBOT)
    for i, m in zip(*np.nonzero(robot)):
        j = cells.source[i, m]
        back = np.flatnonzero(robot[j] & (cells.source[j] == i))[0]
        assert np.array_equal(cells.A[j, back], -cells.A[i, m])
        shift = 0.5 * (radius[i] + radius[j])
        assert np.isclose(cells.b[i, m] + shift, -(cells.b[j, back] + shift), atol=1e-12)


def test_rows_of_robots_at_rest_are_left_alone():
    """No segment (every stop at its estimate): the cells are the point cells, untouched."""
    rng = np.random.default_rng(0)
    p = rng.uniform(-2, 2, (8, 2))
    obstacles = ObstacleSet.build([np.array([[0.0, 0], [0.5, 0], [0.2, 0.4]])], np.zeros((1, 2, 2)), 0.0)
    cells = build_cells(p, np.zeros((8, 2, 2)), np.full(8, 0.1), 1.6, CellGeometry(obstacles, np.zeros((0, 2)), np.zeros(0)), 5.0)
    assert with_braking_segments(cells, p, p.copy(), np.zeros((8, 2, 2)), np.full(8, 0.1), 1.6, obstacles=obstacles) is cells


def test_braking_shrinks_the_braking_segment():
    """S(k+1) ⊂ S(k) under the brake: the stopping point stays (to rounding) and the new
    position lies on the old segment."""
    rng = np.random.default_rng(1)
    for a_max, dt in ((0.3, 0.2), (1.0, 0.1), (4.0, 0.05)):
        params = di.DoubleIntegratorParams(a_max=a_max, v_max=5.0)
        state = np.column_stack([rng.normal(size=(50, 2)), rng.normal(size=(50, 2))])
        for _ in range(30):
            stop = stopping_point(state[:, :2], state[:, 2:], a_max, dt)
            nxt = di.step(state, braking_control(state[:, 2:], a_max, dt), dt, params)
            assert np.allclose(stopping_point(nxt[:, :2], nxt[:, 2:], a_max, dt), stop, atol=1e-12)
            on = np.linalg.norm(nxt[:, :2] - state[:, :2], axis=1) + np.linalg.norm(stop - nxt[:, :2], axis=1)
            assert np.allclose(on, np.linalg.norm(stop - state[:, :2], axis=1), atol=1e-12)
            state = nxt
