"""Exact projection of goals onto cells, against a brute-force optimum."""

import itertools
import math

import numpy as np
from hypothesis import given, settings, strategies as st

from robofleet.avoidance import Cells, project_onto_cells


def brute_force(g, A, b, tol=1e-9):
    """Enumerate g, every edge projection and every vertex; keep the closest feasible."""
    cands = [g]
    for a, off in zip(A, b):
        cands.append(g - (a @ g - off) * a)
    for (a1, b1), (a2, b2) in itertools.combinations(zip(A, b), 2):
        M = np.array([a1, a2])
        if abs(np.linalg.det(M)) > 1e-12:
            cands.append(np.linalg.solve(M, [b1, b2]))
    feas = [c for c in cands if np.all(A @ c <= b + tol)]
    if not feas:
        return None
    return min(feas, key=lambda c: np.linalg.norm(c - g))


def random_cells(rng, n, m):
    A = rng.normal(size=(n, m, 2))
    A /= np.linalg.norm(A, axis=-1, keepdims=True)
    b = rng.uniform(-1.0, 1.5, (n, m))
    valid = rng.random((n, m)) < 0.85
    return Cells(A, np.where(valid, b, 1.0), valid, np.zeros((n, m), np.int8), np.zeros((n, m), np.intp))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(1, 9))
def test_projection_matches_brute_force(seed, m):
    rng = np.random.default_rng(seed)
    cells = random_cells(rng, 30, m)
    goals = rng.normal(size=(30, 2)) * 3
    proj = project_onto_cells(goals, cells)
    for i in range(30):
        A, b = cells.robot(i)
        ref = brute_force(goals[i], A, b)
        if ref is None:
            assert proj.empty[i]
        else:
            assert not proj.empty[i]
            best = np.linalg.norm(ref - goals[i])
            scale = 1.0 + best + np.abs(ref).max()  # nearly parallel lines meet far away
            assert np.linalg.norm(proj.point[i] - goals[i]) <= best + 1e-9 * scale
            assert np.all(A @ proj.point[i] <= b + 1e-8 * scale)


def test_goal_inside_is_returned_unchanged_and_kkt_holds():
    rng = np.random.default_rng(5)
    cells = random_cells(rng, 500, 6)
    goals = rng.normal(size=(500, 2)) * 2
    proj = project_onto_cells(goals, cells)
    inside = cells.contains(goals)
    np.testing.assert_array_equal(proj.point[inside], goals[inside])
    # optimality (KKT): moving from the projection towards any other feasible point never
    # brings it closer to the goal: (g − x*)·(y − x*) ≤ 0 for feasible y (sampled)
    for i in np.flatnonzero(~inside & ~proj.empty)[:100]:
        A, b = cells.robot(i)
        ys = proj.point[i] + rng.normal(size=(400, 2))
        ys = ys[np.all(ys @ A.T <= b, axis=1)]
        assert np.all((ys - proj.point[i]) @ (goals[i] - proj.point[i]) <= 1e-7)


def enumeration(g0, g1, A, b, valid, tol=1e-9, rounding=1e-14):
    """The module docstring's steps 1–4 as plain Python floats, every candidate tried in
    row order (both orders of every pair of rows): ``(x0, x1, k0, k1, empty)``."""
    def excess(x0, x1, k):
        p0, p1 = A[k][0] * x0, A[k][1] * x1
        return p0 + p1 - b[k] - (tol + rounding * (abs(p0) + abs(p1) + abs(b[k])))

    def feasible(x0, x1):
        return all(not valid[k] or excess(x0, x1, k) <= 0 for k in range(len(b)))

    m = len(b)
    slack = [A[k][0] * g0 + A[k][1] * g1 - b[k] for k in range(m)]
    violated = [valid[k] and excess(g0, g1, k) > 0 for k in range(m)]
    if not any(violated):
        return g0, g1, -1, -1, False
    best, out = math.inf, None
    for k in range(m):
        e0, e1 = g0 - slack[k] * A[k][0], g1 - slack[k] * A[k][1]
        if violated[k] and slack[k] < best and feasible(e0, e1):
            best, out = slack[k], (e0, e1, k, -1, False)
    if out is not None:
        return out
    for k, j in itertools.product(range(m), range(m)):
        if not violated[k] or j == k or not valid[j]:
            continue
        (ak0, ak1), (aj0, aj1) = A[k], A[j]
        det = ak0 * aj1 - ak1 * aj0
        if abs(det) <= 1e-12:
            continue
        v0, v1 = (b[k] * aj1 - b[j] * ak1) / det, (ak0 * b[j] - aj0 * b[k]) / det
        r0, r1 = g0 - v0, g1 - v1
        if (r0 * aj1 - r1 * aj0) / det < -tol or (ak0 * r1 - ak1 * r0) / det < -tol:
            continue
        dist = math.sqrt(r0 * r0 + r1 * r1)
        if dist < best and feasible(v0, v1):
            best, out = dist, (v0, v1, k, j, False)
    return out if out is not None else (math.nan, math.nan, -1, -1, True)


def test_projection_is_the_full_enumeration_bit_for_bit():
    """The compiled kernel visits only the valid rows and tries a vertex of two violated
    rows once; its results equal, bit for bit, the enumeration of every candidate in row
    order, on cells with many violated rows, repeated and nearly parallel rows, zero rows,
    zero offsets, and goals at zero and far away."""
    rng = np.random.default_rng(11)
    n, m = 3000, 8
    A = rng.normal(size=(n, m, 2))
    A /= np.linalg.norm(A, axis=-1, keepdims=True)
    A[:, 1] = A[:, 0] + rng.normal(size=(n, 2)) * 1e-13 * (rng.random((n, 1)) < 0.3)
    A[:, 2] = np.where(rng.random((n, 1)) < 0.2, A[:, 3], A[:, 2])
    A[rng.random((n, m)) < 0.03] = 0.0
    b = rng.uniform(-1.0, 1.5, (n, m)) * 10.0 ** rng.uniform(-3, 3, (n, 1))
    b[rng.random((n, m)) < 0.1] = 0.0
    valid = rng.random((n, m)) < 0.85
    cells = Cells(np.where(valid[..., None], A, 0.0), np.where(valid, b, 1.0), valid, np.zeros((n, m), np.int8), np.zeros((n, m), np.intp))
    goals = rng.normal(size=(n, 2)) * 10.0 ** rng.uniform(-2, 3, (n, 1))
    goals[rng.random(n) < 0.02] = 0.0
    proj = project_onto_cells(goals, cells)
    A_, b_, valid_ = cells.A.tolist(), cells.b.tolist(), cells.valid.tolist()
    vertices = 0
    for i in range(n):
        x0, x1, k0, k1, empty = enumeration(float(goals[i, 0]), float(goals[i, 1]), A_[i], b_[i], valid_[i])
        got = (proj.point[i, 0], proj.point[i, 1], proj.active[i, 0], proj.active[i, 1], proj.empty[i])
        assert np.array([x0, x1]).tobytes() == proj.point[i].tobytes() and (k0, k1, empty) == got[2:], (i, got)
        vertices += k1 >= 0
    assert vertices > n // 4 and proj.empty.any()
