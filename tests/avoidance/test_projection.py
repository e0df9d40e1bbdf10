"""Exact projection of goals onto cells, against a brute-force optimum."""

import itertools

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
