"""The compiled passes of the navigation step equal, bit for bit, the numpy expressions
they replace (the right-hand rule's blocked test and second projection, the band return,
the goal checker's distances, the yielding stage's still and parked trackers, the route's
segment test, the blocked products of short rows), on random cells with empty cells, NaN
estimates, zero rows and fleets large enough for the parallel kernels."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.avoidance import Cells, project_onto_cells
from robofleet.avoidance.cell import Kind, cell_rows
from robofleet.avoidance.kernels import BLAS_BLOCK, PARALLEL_MIN_ROBOTS, row_products
from robofleet.avoidance.navigation.band import out_of_the_band
from robofleet.avoidance.navigation.goal import GoalChecker, goal_distances
from robofleet.avoidance.navigation.params import RightHandParams, YieldingParams
from robofleet.avoidance.navigation.progress import ParkedTest
from robofleet.avoidance.navigation.right_hand import blocked_by_robot, right_hand_goals, turned_projection
from robofleet.avoidance.navigation.yielding import ParkingState, StillTracker
from robofleet.avoidance.navigation.route import Halfplanes, gap_blockers, grown_polygons, halfplanes, segments_free
from robofleet.avoidance.projection import Projection, project_rows_into
from robofleet.avoidance.random_scenarios import random_convex_polygon

SIZES = [300, PARALLEL_MIN_ROBOTS + 777]  # the serial and the parallel kernels


def random_cells(rng, n: int, m: int) -> Cells:
    """Random unit rows of every kind, a few zero rows, ~15 % padding, some empty cells."""
    A = rng.normal(size=(n, m, 2))
    A /= np.linalg.norm(A, axis=-1, keepdims=True)
    A[rng.random((n, m)) < 0.02] = 0.0  # degenerate rows: ‖a‖ = 0 < 1e-12
    b = rng.uniform(-1.0, 1.5, (n, m))
    valid = rng.random((n, m)) < 0.85
    kind = rng.integers(0, 3, (n, m)).astype(np.int8)
    return Cells(np.where(valid[..., None], A, 0.0), np.where(valid, b, 1.0), valid, kind, rng.integers(0, 50, (n, m)))


def random_estimates(rng, n: int) -> np.ndarray:
    p = rng.normal(size=(n, 2)) * 10.0 ** rng.uniform(-1, 2, (n, 1))
    p[rng.random(n) < 0.01] = np.nan
    return p


# -- the numpy expressions the compiled passes replace -----------------------------------
def numpy_blocked(estimates, active, cells, near):
    rows = np.arange(len(estimates))[:, None]
    act = np.maximum(active, 0)
    a, b = cells.A[rows, act], cells.b[rows, act]
    with np.errstate(invalid="ignore"):
        gap = (b - np.einsum("nkc,nc->nk", a, estimates)) / np.maximum(np.linalg.norm(a, axis=-1), 1e-12)
        robot_face = (active >= 0) & (cells.kind[rows, act] == Kind.ROBOT) & (gap < near)
    return robot_face.any(axis=1)


def numpy_turned_projection(estimates, targets, proj, cells, driving, params):
    turn = numpy_blocked(estimates, proj.active, cells, params.face_near) & driving & ~proj.empty
    if not turn.any():
        return proj
    rows = np.flatnonzero(turn)
    goals = (targets[rows] - estimates[rows]) @ turn_matrix(params.angle).T + estimates[rows]
    turned = project_onto_cells(goals, cell_rows(cells, rows))
    keep = rows[~turned.empty]
    point, active = proj.point.copy(), proj.active.copy()
    point[keep], active[keep] = turned.point[~turned.empty], turned.active[~turned.empty]
    return Projection(point, proj.empty, active)


def turn_matrix(angle_deg):
    c, s = np.cos(np.deg2rad(angle_deg)), np.sin(np.deg2rad(angle_deg))
    return np.array([[c, s], [-s, c]])


def numpy_out_of_the_band(estimates, proj, cells, depth):
    with np.errstate(invalid="ignore"):
        slack = np.einsum("nkc,nc->nk", cells.A, estimates) - cells.b
        norm = np.maximum(np.linalg.norm(cells.A, axis=-1), 1e-12)
        deep = ~proj.empty & np.any(cells.valid & (cells.kind == Kind.OBSTACLE) & (slack / norm > depth), axis=1)
    if not deep.any():
        return proj
    idx = np.flatnonzero(deep)
    back = project_onto_cells(estimates[idx], cell_rows(cells, idx))
    point = proj.point.copy()
    point[idx] = np.where(back.empty[:, None], point[idx], back.point)
    return Projection(point, proj.empty, proj.active)


def assert_same_projection(got: Projection, expected: Projection):
    for a, b in zip((got.point, got.empty, got.active), (expected.point, expected.empty, expected.active)):
        np.testing.assert_array_equal(a, b)


# -- the tests -----------------------------------------------------------------------------
@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("seed", range(3))
def test_blocked_test_is_the_numpy_expression(n, seed):
    rng = np.random.default_rng(seed)
    cells, p = random_cells(rng, n, 7), random_estimates(rng, n)
    proj = project_onto_cells(rng.normal(size=(n, 2)) * 3, cells)
    for near in (0.05, 0.5, np.inf):
        np.testing.assert_array_equal(blocked_by_robot(p, proj.active, cells, near), numpy_blocked(p, proj.active, cells, near))


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("seed", range(3))
def test_turned_projection_is_the_reprojection_of_the_gathered_rows(n, seed):
    """Only the blocked driving robots are turned and projected again, each right after
    its first projection, in place of gathering their cells; every other row, and every
    empty turned cell, keeps the first projection."""
    rng = np.random.default_rng(10 + seed)
    cells, p = random_cells(rng, n, 6), random_estimates(rng, n)
    targets = p + rng.normal(size=(n, 2)) * 5
    proj = project_onto_cells(targets, cells)
    driving = rng.random(n) < 0.8
    params = RightHandParams(angle=float(rng.uniform(10, 80)), face_near=float(rng.uniform(0.2, 2.0)))
    got = turned_projection(p, targets, cells, driving, params)
    assert_same_projection(got, numpy_turned_projection(p, targets, proj, cells, driving, params))
    assert not np.array_equal(got.point, proj.point, equal_nan=True)  # some robots did turn


@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("seed", range(3))
def test_band_return_is_the_numpy_expression(n, seed):
    rng = np.random.default_rng(20 + seed)
    cells, p = random_cells(rng, n, 6), random_estimates(rng, n)
    proj = project_onto_cells(p + rng.normal(size=(n, 2)), cells)
    for depth in (0.0, 0.3):
        got, expected = out_of_the_band(p, proj, cells, depth), numpy_out_of_the_band(p, proj, cells, depth)
        assert_same_projection(got, expected)
        assert got is not proj  # some estimates lie deep beyond an obstacle face


@pytest.mark.parametrize("seed", range(3))
def test_rows_projected_in_place_are_the_projection_of_the_gathered_rows(seed):
    rng = np.random.default_rng(30 + seed)
    n = PARALLEL_MIN_ROBOTS + 100
    cells = random_cells(rng, n, 8)
    rows = np.sort(rng.choice(n, PARALLEL_MIN_ROBOTS + 10, replace=False))
    goals = rng.normal(size=(len(rows), 2)) * 4
    point, active = rng.normal(size=(n, 2)), rng.integers(-1, 8, (n, 2))
    expected_point, expected_active = point.copy(), active.copy()
    ref = project_onto_cells(goals, cell_rows(cells, rows))
    keep = rows[~ref.empty]
    expected_point[keep], expected_active[keep] = ref.point[~ref.empty], ref.active[~ref.empty]
    assert ref.empty.any() and not ref.empty.all()
    project_rows_into(point, active, rows, goals, cells)
    np.testing.assert_array_equal(point, expected_point)
    np.testing.assert_array_equal(active, expected_active)


@pytest.mark.parametrize("dim", [2, 3])
def test_goal_distances_are_numpys_norm(dim):
    rng = np.random.default_rng(dim)
    p = rng.normal(size=(20000, dim)) * 10.0 ** rng.uniform(-8, 8, (20000, 1))
    g = rng.normal(size=(20000, dim))
    p[::97] = np.nan
    p[1::97] = np.inf
    np.testing.assert_array_equal(goal_distances(p, g), np.linalg.norm(g - p, axis=1))
    checker = GoalChecker.initial(len(p), 5.0)
    checker.observe(p, g)
    np.testing.assert_array_equal(checker.within, np.linalg.norm(g - p, axis=1) <= 5.0)
    np.testing.assert_array_equal(checker.arrived, checker.within)


@pytest.mark.parametrize("n", [1, 3, 17, 2 * BLAS_BLOCK - 1, 2 * BLAS_BLOCK, 2 * BLAS_BLOCK + 1, 5 * BLAS_BLOCK + 3, 100_003])
@pytest.mark.parametrize("k", [2, 3])
def test_row_products_are_one_product_bit_for_bit(n, k):
    rng = np.random.default_rng(n + k)
    x = rng.normal(size=(n, k)) * 10.0 ** rng.uniform(-3, 3, (n, 1))
    matrix = np.linalg.cholesky(np.cov(rng.normal(size=(k, 3 * k)))).T
    np.testing.assert_array_equal(row_products(x, matrix), x @ matrix)
    np.testing.assert_array_equal(right_hand_goals(x[:, :2], x[:, :2][::-1], np.deg2rad(33.0)),
                                  (x[:, :2][::-1] - x[:, :2]) @ turn_matrix(33.0).T + x[:, :2])


@pytest.mark.parametrize("n", [5, 2 * BLAS_BLOCK + 17, 40_000])
def test_turned_goals_of_some_rows_are_those_of_the_gathered_rows(n):
    """The right-hand turn of the rows ``rows`` (differences and sums taken without gathering)
    equals the turn of the gathered rows, NaN estimates included."""
    rng = np.random.default_rng(n)
    p = random_estimates(rng, n)
    g = p + rng.normal(size=(n, 2)) * 10.0 ** rng.uniform(-3, 3, (n, 1))
    rows = np.flatnonzero(rng.random(n) < 0.8)
    angle = np.deg2rad(float(rng.uniform(5, 85)))
    np.testing.assert_array_equal(right_hand_goals(p, g, angle, rows), right_hand_goals(p[rows], g[rows], angle))


def numpy_segments_free(a, b, obstacles: Halfplanes):
    """The Cyrus–Beck test as numpy array expressions over ``(S, O, K)``."""
    if obstacles.A.shape[0] == 0:
        return np.ones(len(a), bool)
    d = b - a
    na = np.einsum("okc,sc->sok", obstacles.A, a) - obstacles.b[None]
    nd = np.einsum("okc,sc->sok", obstacles.A, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -na / nd
        entering, leaving = nd < -1e-9, nd > 1e-9
        t_lo = np.max(np.where(entering, t, 0.0), axis=2)
        t_hi = np.min(np.where(leaving, t, 1.0), axis=2)
        outside_parallel = np.any((np.abs(nd) <= 1e-9) & (na >= -1e-9), axis=2)
        length = np.linalg.norm(d, axis=1)[:, None]
        crosses = ~outside_parallel & ((t_hi - t_lo) * length > 1e-6)
    return ~np.any(crosses, axis=1)


@pytest.mark.parametrize("seed", range(4))
def test_segment_test_is_the_numpy_expression(seed):
    """Random segments against grown random polygons and the thin walls across gaps, with
    segments that run along edges, start on vertices, have no length, or hold NaN/inf."""
    rng = np.random.default_rng(40 + seed)
    polygons = [np.asarray(random_convex_polygon(rng, rng.uniform(-3, 3, 2), rng.uniform(0.3, 1.0))) for _ in range(5)]
    planes = halfplanes(grown_polygons(polygons, 0.2) + gap_blockers(polygons, 1.5))
    vertices = np.concatenate(grown_polygons(polygons, 0.2))
    n = PARALLEL_MIN_ROBOTS + 3000
    a, b = rng.uniform(-4, 4, (n, 2)), rng.uniform(-4, 4, (n, 2))
    a[:500] = vertices[rng.integers(0, len(vertices), 500)]  # from a vertex along its polygon's edges or through it
    b[:250] = vertices[rng.integers(0, len(vertices), 250)]
    b[500:600] = a[500:600]  # no length
    a[600:610] = np.nan
    b[610:620] = np.inf
    for rows in (slice(0, 300), slice(None)):  # the serial and the parallel kernel
        np.testing.assert_array_equal(segments_free(a[rows], b[rows], planes), numpy_segments_free(a[rows], b[rows], planes))
    assert 0.2 < segments_free(a, b, planes).mean() < 0.9


# -- the yielding stage's trackers -----------------------------------------------------------
def numpy_still(mean, still, estimates, radius, steps):
    """:class:`StillTracker`'s rule as numpy expressions: the new ``(mean, still)``."""
    mean = mean.copy()
    fresh = ~np.isfinite(mean[:, 0])
    mean[fresh] = estimates[fresh]
    mean += (estimates - mean) * (2.0 / steps)
    return mean, np.where(np.linalg.norm(estimates - mean, axis=1) < radius, still + 1, 0)


def numpy_parked(anchor, since, estimates, rest, mean, radius, steps):
    """:class:`ParkedTest`'s rule as numpy expressions: the new ``(anchor, since, parked)``."""
    if steps <= 0:
        return anchor, since, np.zeros(len(estimates), bool)
    anchor = anchor.copy()
    anchored = np.isfinite(anchor[:, 0])
    fresh = rest & ~anchored
    anchor[fresh] = mean[fresh]
    anchored |= fresh
    with np.errstate(invalid="ignore"):
        gone = anchored & (np.linalg.norm(estimates - np.where(anchored[:, None], anchor, 0.0), axis=1) > radius)
    anchor[gone] = np.nan
    since = np.where(anchored & ~gone, since + 1, 0)
    return anchor, since, since >= steps


def wandering_estimates(rng, n: int, dim: int, steps: int):
    """Estimates of robots that sit, jitter, drift and jump, some NaN, some far away."""
    base = rng.normal(size=(n, dim)) * 10.0 ** rng.uniform(-1, 3, (n, 1))
    drift = rng.normal(size=(n, dim)) * np.where(rng.random((n, 1)) < 0.3, 0.2, 0.0)
    for k in range(steps):
        est = base + k * drift + rng.normal(size=(n, dim)) * rng.choice([0.0, 0.05, 0.5], (n, 1))
        jump = rng.random(n) < 0.03
        est[jump] += rng.normal(size=(jump.sum(), dim)) * 3.0
        est[rng.random(n) < 0.01] = np.nan
        yield est


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(3))
def test_still_tracker_is_the_numpy_expression(dim, seed):
    rng = np.random.default_rng(50 + seed)
    n, radius, steps = 3000, float(rng.uniform(0.2, 1.0)), int(rng.integers(1, 6))
    tracker = StillTracker.initial(n, dim)
    mean, still = tracker.mean.copy(), tracker.still.copy()
    for est in wandering_estimates(rng, n, dim, 25):
        counts = tracker.observe(est, radius, steps)
        mean, still = numpy_still(mean, still, est, radius, steps)
        np.testing.assert_array_equal(tracker.mean, mean)
        np.testing.assert_array_equal(counts, still)
        assert counts.dtype == still.dtype
    assert (still >= steps).any() and (still == 0).any()


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(3))
def test_parked_test_is_the_numpy_expression(dim, seed):
    rng = np.random.default_rng(60 + seed)
    n, radius, steps = 3000, float(rng.uniform(0.3, 1.5)), int(rng.integers(0, 6))
    test = ParkedTest.initial(n, dim)
    anchor, since = test.anchor.copy(), test.since.copy()
    mean = np.full((n, dim), np.nan)
    for est in wandering_estimates(rng, n, dim, 25):
        mean = np.where(np.isfinite(mean), 0.7 * mean + 0.3 * est, est)
        rest = rng.random(n) < 0.4
        parked = test.observe(est, rest, mean, radius, steps)
        anchor, since, expected = numpy_parked(anchor, since, est, rest, mean, radius, steps)
        np.testing.assert_array_equal(test.anchor, anchor)
        np.testing.assert_array_equal(test.since, since)
        np.testing.assert_array_equal(parked, expected)


@pytest.mark.parametrize("parked_steps", [0, 4])
@pytest.mark.parametrize("seed", range(3))
def test_parking_observation_is_the_two_trackers_in_turn(parked_steps, seed):
    """The fused pass of :meth:`ParkingState.observe` equals the still tracker's update
    followed by the parked test on its new mean, as numpy expressions."""
    rng = np.random.default_rng(70 + seed)
    n = 3000
    params = YieldingParams(still_radius=float(rng.uniform(0.2, 0.6)), still_steps=int(rng.integers(1, 5)),
                            max_aside=float(rng.uniform(0.1, 1.0)), parked_steps=parked_steps)
    state = ParkingState.initial(n)
    mean, still = state.stillness.mean.copy(), state.stillness.still.copy()
    anchor, since = state.resting.anchor.copy(), state.resting.since.copy()
    seen = np.zeros(n, bool)
    for est in wandering_estimates(rng, n, 2, 30):
        got_still, got_resting = state.observe(est, params)
        mean, still = numpy_still(mean, still, est, params.still_radius, params.still_steps)
        rest = still >= params.still_steps
        anchor, since, resting = numpy_parked(anchor, since, est, rest, mean, params.max_aside + params.still_radius, params.parked_steps)
        np.testing.assert_array_equal(got_still, rest)
        np.testing.assert_array_equal(got_resting, resting)
        for got, expected in ((state.stillness.mean, mean), (state.stillness.still, still), (state.resting.anchor, anchor),
                              (state.resting.since, since)):
            np.testing.assert_array_equal(got, expected)
        seen |= resting
    assert seen.any() == (parked_steps > 0)
