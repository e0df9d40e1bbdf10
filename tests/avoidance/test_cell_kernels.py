"""The compiled cell builder and neighbour search: same cells as the pairwise form, same
neighbours as a k-d tree / brute force, same results on any number of threads."""

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
import pytest
from scipy.spatial import cKDTree

from robofleet.avoidance import kernels
from robofleet.avoidance.cell import (
    GRID_CELLS_MAX,
    CellGeometry,
    _obstacle_rows,
    _pad,
    _robot_rows,
    _shared_mode,
    _wall_rows,
    build_cells,
    grid_fits,
    neighbour_pairs,
)
from robofleet.avoidance.neighbours import (
    box_neighbours,
    nearest_neighbours,
    sort_by_cell,
)
from robofleet.avoidance.obstacles import ObstacleSet, wall_planes
from robofleet.avoidance.projection import project_onto_cells
from robofleet.avoidance.separator import separator_mode
from robofleet.core.errors import ConfigError


def geometry_with_obstacles() -> CellGeometry:
    boxes = [np.array([[-1.0, -1.0], [0.0, -1.0], [0.0, 0.0], [-1.0, 0.0]]), np.array([[2.0, 2.0], [3.0, 2.5], [2.2, 3.0]])]
    obstacles = ObstacleSet.build(boxes, np.repeat((0.05**2 * np.eye(2))[None], 2, 0), 0.05)
    return CellGeometry(obstacles, *wall_planes(np.array([[-6.0, -6.0], [6.0, -6.0], [6.0, 6.0], [-6.0, 6.0]])))


def row_sets(cells):
    """Each robot's valid rows as a sorted list (row order is not part of a cell)."""
    return [sorted(zip(cells.kind[i][cells.valid[i]].tolist(), cells.source[i][cells.valid[i]].tolist(),
                       map(tuple, cells.A[i][cells.valid[i]].tolist()), cells.b[i][cells.valid[i]].tolist())) for i in range(len(cells.A))]


@pytest.mark.parametrize("cov", [0.1**2 * np.eye(2), np.diag([0.02, 0.004]), np.array([[0.02, 0.006], [0.006, 0.01]]), np.zeros((2, 2))])
def test_shared_covariance_kernel_builds_the_pairwise_cells(cov):
    """The per-robot kernel gives every robot the rows the pair-once form gives it: the
    separator of each pair, its negation for the other robot, obstacles and walls."""
    rng = np.random.default_rng(4)
    p = rng.uniform(-5.5, 5.5, (150, 2))
    covs, radius, geo = np.broadcast_to(cov, (150, 2, 2)), rng.uniform(0.1, 0.3, 150), geometry_with_obstacles()
    fast = build_cells(p, covs, radius, 1.63, geo, 2.0)
    parts = [_robot_rows(p, covs, radius, 1.63, neighbour_pairs(p, 2.0)), _obstacle_rows(p, covs, radius, 1.63, geo.obstacles, 2.0),
             _wall_rows(p, covs, radius, 1.63, geo, 2.0)]
    slow = _pad(150, 2, parts)
    assert fast.A.shape == slow.A.shape
    for got, want in zip(row_sets(fast), row_sets(slow)):
        assert [r[:2] for r in got] == [r[:2] for r in want]
        np.testing.assert_allclose([r[2] + (r[3],) for r in got], [r[2] + (r[3],) for r in want], rtol=0, atol=1e-12)
    assert np.all(fast.A[~fast.valid] == 0) and np.all(fast.b[~fast.valid] == 1) and np.all(fast.kind[~fast.valid] == -1)


def test_reciprocal_rows_are_exact_negations():
    """Robot j's row for the pair (i, j) is exactly (−a, −b) (appendix B; no buffers here)."""
    rng = np.random.default_rng(5)
    p = rng.uniform(0, 8, (200, 2))
    cells = build_cells(p, np.broadcast_to(np.array([[0.02, 0.004], [0.004, 0.01]]), (200, 2, 2)), np.zeros(200), 0.0,
                        CellGeometry(ObstacleSet.build([], np.zeros((0, 2, 2)), 0.0), np.zeros((0, 2)), np.zeros(0)), 2.0)
    for i in range(200):
        for r in np.flatnonzero(cells.valid[i]):
            j = cells.source[i, r]
            back = np.flatnonzero(cells.valid[j] & (cells.source[j] == i))
            assert len(back) == 1
            assert np.array_equal(cells.A[j, back[0]], -cells.A[i, r])
            assert cells.b[j, back[0]] == -cells.b[i, r]


def test_box_neighbours_match_a_kd_tree():
    rng = np.random.default_rng(6)
    for n in (1, 2, 40, 800):
        p = rng.uniform(0, 15, (n, 2))
        p[: n // 4] = np.round(p[: n // 4])  # exact ties on the box boundary
        start, index = box_neighbours(p, 1.0)
        got = {(i, int(j)) for i in range(n) for j in index[start[i]:start[i + 1]]}
        pairs = cKDTree(p).query_pairs(1.0, p=np.inf) if n > 1 else set()
        assert got == pairs | {(j, i) for i, j in pairs}
        assert all(np.all(np.diff(index[start[i]:start[i + 1]]) > 0) for i in range(n))


def test_box_neighbours_of_far_apart_clusters_match_a_kd_tree():
    """Clusters 10⁵ cells apart: the keys are sorted by comparison instead of counting."""
    rng = np.random.default_rng(9)
    p = np.concatenate([rng.uniform(0, 4, (60, 2)), rng.uniform(0, 4, (60, 2)) + [1e5, -3e4]])
    start, index = box_neighbours(p, 1.0)
    got = {(i, int(j)) for i in range(len(p)) for j in index[start[i]:start[i + 1]]}
    pairs = cKDTree(p).query_pairs(1.0, p=np.inf)
    assert got == pairs | {(j, i) for i, j in pairs}


@pytest.mark.parametrize("spread", [15.0, 1e6])
def test_points_are_sorted_by_cell_key_then_index(spread):
    """Both sorting paths give the order of (cell key, index), with one run per occupied cell."""
    rng = np.random.default_rng(10)
    p = np.round(rng.uniform(0, spread, (700, 2)) * 4) / 4  # points on cell borders too
    runs = sort_by_cell(p, 1.0)
    cell = np.floor((p - p.min(axis=0)) / 1.0).astype(np.int64)
    key = cell[:, 0] * runs.rows + cell[:, 1]
    assert runs.order.tolist() == np.lexsort((np.arange(len(p)), key)).tolist()
    assert runs.cell_key.tolist() == np.unique(key).tolist()
    assert np.array_equal(key[runs.order], np.repeat(runs.cell_key, np.diff(runs.start)))
    assert np.array_equal(runs.sorted_points, p[runs.order])


def test_nearest_neighbours_match_brute_force_with_ties():
    rng = np.random.default_rng(7)
    p = np.round(rng.uniform(0, 12, (500, 2)) * 2) / 2  # many equal distances
    index, count = nearest_neighbours(p, 10, 3.0)
    d2 = np.sum((p[:, None] - p[None]) ** 2, axis=-1)
    for i in range(len(p)):
        d2[i, i] = np.inf
        order = [j for j in np.lexsort((np.arange(len(p)), d2[i])) if d2[i, j] < 9.0][:10]
        assert index[i, : count[i]].tolist() == order
        assert np.all(index[i, count[i]:] == -1)


def test_kernels_give_identical_results_on_one_and_two_threads(monkeypatch):
    """Robots are independent in every kernel: the thread count changes nothing, bit for bit."""
    from robofleet.avoidance.navigation.yielding import StillTracker
    from robofleet.avoidance.orca import OrcaParams, orca_velocities

    monkeypatch.setattr(kernels, "PARALLEL_MIN_ROBOTS", 1)
    rng = np.random.default_rng(8)
    p = rng.uniform(-5.5, 5.5, (600, 2))
    vel, pref = rng.normal(size=(600, 2)) * 0.2, rng.normal(size=(600, 2)) * 0.4
    covs, geo = np.broadcast_to(0.01 * np.eye(2), (600, 2, 2)), geometry_with_obstacles()
    results = []
    for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
        kernels.set_threads(threads)
        cells = build_cells(p, covs, np.full(600, 0.2), 1.63, geo, 2.0)
        proj = project_onto_cells(-p, cells)
        v, infeasible = orca_velocities(p, vel, pref, 0.2, 0.4, OrcaParams(), 0.1)
        inside = cells.contains(p + vel)
        still = StillTracker.initial(600)
        for estimates in (p, p + 0.01 * vel, p + 0.2 * vel):
            still.observe(estimates, 0.05, 10)
        results.append((cells.A, cells.b, cells.source, proj.point, proj.active, v, infeasible, inside, still.mean, still.still))
    kernels.set_threads(numba.config.NUMBA_NUM_THREADS)
    for a, b in zip(*results):
        assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("bad", [0, -1, 10**6, 1.5, True])
def test_thread_setting_refuses_bad_counts(bad):
    with pytest.raises(ConfigError, match="threads"):
        kernels.set_threads(bad)


def obstacles_from_bounds(lo: np.ndarray, hi: np.ndarray) -> ObstacleSet:
    """An obstacle set carrying only the bounds the local-box selection reads."""
    o, d = lo.shape
    return ObstacleSet(np.zeros((o, 1, d)), np.zeros((o, d, d)), np.zeros(o), lo, hi)


@pytest.mark.parametrize("seed", range(40))
def test_obstacles_near_a_point_match_the_all_pairs_test(seed):
    """The bucketed selection equals ``np.nonzero`` of the (N, O) local-box test, order
    included: 2-D and 3-D, clusters far apart, obstacles of every size (huge ones force
    the all-pairs path), points exactly on a grown bound, NaN and infinite coordinates, and a zero, NaN or infinite reach."""
    rng = np.random.default_rng(seed)
    d = int(rng.choice([2, 3]))
    n, o = int(rng.integers(0, 300)), int(rng.integers(0, 60))
    centres = rng.choice([0.0, 1e4, -3e5], size=(n, 1)) + rng.uniform(-8, 8, (n, d))
    corners = rng.choice([0.0, 1e4], size=(o, 1)) + rng.uniform(-9, 9, (o, d))
    size = rng.choice([0.01, 0.5, 3.0, 1e5], size=(o, 1), p=[0.2, 0.5, 0.28, 0.02]) * rng.random((o, d))
    lo, hi = corners, corners + size
    reach = float(rng.choice([0.0, 0.4, 2.0, 7.0, np.nan, np.inf]))
    if n and o:  # points exactly on a grown bound, and a few not finite
        k = rng.integers(0, n, size=min(n, 20))
        centres[k, 0] = lo[rng.integers(0, o, size=len(k)), 0] - reach
        centres[rng.integers(0, n, size=3), rng.integers(0, d, size=3)] = rng.choice([np.nan, np.inf, -np.inf], size=3)
    with np.errstate(invalid="ignore"):  # inf − inf in the reference test: NaN, false
        near = np.all(centres[:, None] + reach >= lo[None], axis=-1) & np.all(centres[:, None] - reach <= hi[None], axis=-1)
    expected = np.nonzero(near)
    owner, index = obstacles_from_bounds(lo, hi).near(centres, reach)
    assert np.array_equal(owner, expected[0]) and np.array_equal(index, expected[1])


@pytest.mark.parametrize("seed", range(4))
def test_grid_fits_is_the_extent_test_on_the_first_axis(seed):
    """``grid_fits`` takes the extent of the transposed estimates; it decides as the
    extent along the first axis of ``(N, 2)`` does, with NaN, infinite and far-flung
    estimates."""
    rng = np.random.default_rng(seed)
    seen = set()
    for _ in range(80):
        n = int(rng.integers(1, 400))
        p = rng.normal(size=(n, 2)) * 10.0 ** rng.uniform(-2, 12) * 10.0 ** rng.uniform(0, 3, (n, 1))
        if rng.random() < 0.3:
            p[rng.integers(0, n), rng.integers(0, 2)] = rng.choice([np.nan, np.inf, -np.inf])
        box = float(10.0 ** rng.uniform(-3, 3))
        with np.errstate(over="ignore", invalid="ignore"):
            expected = bool(np.prod(np.ptp(p, axis=0) / box + 1.0) < GRID_CELLS_MAX)
        assert grid_fits(p, box) == expected
        seen.add(expected)
    assert seen == {True, False}


def test_shared_separator_mode_is_remembered_per_covariance():
    """The prepared shared Σ is the one of the Σ asked for, whatever was asked before:
    diagonal, general, zero and negative-zero entries, one pair or several."""
    rng = np.random.default_rng(22)
    covs = [np.diag([0.01, 0.04]), np.array([[0.02, 0.005], [0.005, 0.03]]), np.zeros((2, 2)), np.diag([-0.0, 0.0]),
            np.diag([0.01, 0.01])]
    for _ in range(60):
        cov, pairs = covs[rng.integers(len(covs))], int(rng.integers(0, 4))
        mode, solve = _shared_mode(cov, pairs)
        expected_mode, expected_solve = separator_mode(cov, pairs=pairs)
        assert mode == expected_mode and solve.tobytes() == expected_solve.tobytes()


def test_reused_arrays_are_never_ones_still_referenced():
    """``kernels.reused_array`` hands out a buffer again only once no array or view made
    from it is left: arrays kept (or views of them) keep their values through later
    requests of every shape, and released buffers are reused."""
    rng = np.random.default_rng(12)
    held, reused, seen = [], 0, set()
    for step in range(400):
        shape = (int(rng.integers(1, 50)), int(rng.integers(1, 4)))
        array = kernels.reused_array("test.reuse", shape, np.float64)
        reused += id(array.base) in seen
        seen.add(id(array.base))
        array[...] = step
        if rng.random() < 0.5:
            held.append((step, array if rng.random() < 0.5 else array[: max(1, shape[0] // 2)]))
        if held and rng.random() < 0.4:
            held.pop(int(rng.integers(len(held))))
        del array
        for value, kept in held:
            assert np.all(kept == value)
    assert reused > 100


def test_arrays_beyond_the_kept_size_are_fresh(monkeypatch):
    monkeypatch.setattr(kernels, "KEEP_BYTES", 800)
    for make in (kernels.reused_array, kernels.work_array):
        small = [id(make(f"test.{make.__name__}", (10, 10), np.float64).base) for _ in range(3)]
        large = [make(f"test.{make.__name__}.large", (10, 11), np.float64) for _ in range(3)]
        assert len(set(small)) == 1 and all(a.base is None and a.shape == (10, 11) for a in large)


def test_cells_kept_by_the_caller_are_not_overwritten_by_later_cells():
    """The cells' arrays come from reused buffers: cells a caller keeps stay as built while
    the next steps' cells are built, on this thread and on another."""
    rng = np.random.default_rng(13)
    covs, geo = np.broadcast_to(0.01 * np.eye(2), (300, 2, 2)), geometry_with_obstacles()

    def build(seed):
        p = np.random.default_rng(seed).uniform(-5.5, 5.5, (300, 2))
        return build_cells(p, covs, np.full(300, 0.2), 1.63, geo, 2.0)

    first = build(0)
    expected = [x.copy() for x in (first.A, first.b, first.valid, first.kind, first.source)]
    row = first.A[7]
    for seed in rng.integers(1, 1000, 6):
        build(int(seed))
    with ThreadPoolExecutor(2) as pool:
        list(pool.map(build, range(50, 56)))
    for got, want in zip((first.A, first.b, first.valid, first.kind, first.source), expected):
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(row, expected[0][7])
    again = build(0)
    for got, want in zip((again.A, again.b, again.valid, again.kind, again.source), expected):
        np.testing.assert_array_equal(got, want)


def test_run_buffers_keep_arrays_of_any_size_and_let_the_large_ones_go_after(monkeypatch):
    """Within ``kernels.run_buffers`` arrays beyond ``KEEP_BYTES`` are kept and reused (a
    run's steps reuse their cells however large the fleet); leaving the outermost block
    lets them go, keeps the small ones, and leaves arrays still held intact."""
    monkeypatch.setattr(kernels, "KEEP_BYTES", 800)
    for make in (kernels.reused_array, kernels.work_array):
        key = f"test.run.{make.__name__}"
        small = id(make(key + ".small", (10, 10), np.float64).base)
        with kernels.run_buffers():
            with kernels.run_buffers():
                large = [id(make(key, (10, 11), np.float64).base) for _ in range(3)]
            held = make(key, (10, 11), np.float64)
            held[...] = 7.0
            assert len(set(large)) == 1 and id(held.base) == large[0]
        assert make(key, (10, 11), np.float64).base is None
        assert id(make(key + ".small", (10, 10), np.float64).base) == small
        np.testing.assert_array_equal(held, 7.0)


def test_a_run_reusing_its_large_buffers_reproduces_one_allocating_them_afresh(monkeypatch):
    """A navigation-on run whose every cell array comes from a kept buffer (all of them
    beyond ``KEEP_BYTES``, reused step after step within ``run_buffers``), its kernels on
    two threads, records the same trace, bit for bit, as one allocating every array
    afresh on one thread (the buffers' stale contents never reach a result)."""
    import contextlib

    import robofleet
    from robofleet.avoidance import simulation

    spec = robofleet.load_scenario({"family": "avoidance", "name": "swap", "max_steps": 30, "record_cells": False,
                                    "workspace": {"bounds": [-5, -5, 5, 5], "obstacles": [{"center": [0, 2.5], "size": [1, 1]}]},
                                    "robots": {"n": 24, "radius": 0.2, "v_max": 0.4, "sigma": 0.1, "layout": {"kind": "circle", "radius": 4.0}},
                                    "navigation": {"enabled": True}})
    monkeypatch.setattr(kernels, "KEEP_BYTES", 0)
    monkeypatch.setattr(kernels, "PARALLEL_MIN_ROBOTS", 1)
    try:
        kernels.set_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        reused = robofleet.simulate(spec, seed=5)
        monkeypatch.setattr(simulation, "run_buffers", contextlib.nullcontext)
        kernels.set_threads(1)
        fresh = robofleet.simulate(spec, seed=5)
    finally:
        kernels.set_threads(numba.config.NUMBA_NUM_THREADS)
    assert reused.arrays.keys() == fresh.arrays.keys()
    for name in fresh.arrays:
        if name != "step_seconds":
            np.testing.assert_array_equal(reused.arrays[name], fresh.arrays[name], err_msg=name)
