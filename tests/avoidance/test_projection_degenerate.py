"""The projection kernel on degenerate cells: bit for bit the enumeration of every
candidate, and the closest point of the cell to the target (a brute-force optimum), for
both projections of the right-hand stage.

Cells: three or more rows through one vertex with the target projecting onto it, the
target on a vertex, repeated, parallel and antiparallel rows, empty strips, cells of
1e-10 m, rows through the origin, and B-UAVC-like cells of a robot among neighbours
1,000 m from the origin with targets 2,000 m away (the circle swap's geometry)."""

from __future__ import annotations

import numpy as np

from robofleet.avoidance import Cells, project_onto_cells
from robofleet.avoidance.cell import Kind
from robofleet.avoidance.navigation.params import RightHandParams
from robofleet.avoidance.navigation.right_hand import blocked_by_robot, right_hand_goals, turned_projection

from .test_projection import brute_force, enumeration

ROWS = 7


def _unit(rng, n):
    a = rng.normal(size=(n, 2))
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def concurrent_cell(rng):
    """Three to five rows through one vertex (the rest random), the target beyond it; a
    quarter of the vertices at the origin (zero offsets: the signs of zeros count)."""
    vertex = rng.normal(size=2) * 10.0 ** rng.uniform(-2, 3) * (rng.random() >= 0.25)
    through = int(rng.integers(3, 6))
    A, b = _unit(rng, ROWS), rng.uniform(0.1, 2.0, ROWS)
    A[:through] = _unit(rng, through)
    b[:through] = A[:through] @ vertex
    b[through:] += A[through:] @ vertex
    pick = rng.choice(through, 2, replace=False)
    target = vertex + A[pick].T @ rng.uniform(0.0, 3.0, 2)
    if rng.random() < 0.25:
        target = vertex.copy()  # the target on the vertex
    return A, b, target


def parallel_cell(rng):
    """Repeated, parallel and antiparallel rows (an empty strip in a quarter of the cells)."""
    A, b = _unit(rng, ROWS), rng.uniform(-0.5, 2.0, ROWS)
    A[1], b[1] = A[0], b[0]  # repeated
    A[2], b[2] = A[0], b[0] + rng.choice([0.0, 1e-12, 1e-9, 0.3])  # parallel
    A[3] = -A[0]
    b[3] = -b[0] + rng.choice([-0.5, 0.0, 0.5]) * (rng.random() < 0.25) + rng.uniform(0.0, 1.0) * (rng.random() >= 0.25)
    A[4] = A[5] + rng.normal(size=2) * 1e-13  # nearly parallel
    A[4] /= np.linalg.norm(A[4])
    return A, b, rng.normal(size=2) * 3.0


def tiny_cell(rng):
    """A cell of about 1e-10 m around the origin."""
    A = _unit(rng, ROWS)
    return A, rng.uniform(0.0, 1e-10, ROWS), rng.normal(size=2) * 10.0 ** rng.uniform(-12, 1)


def bvc_like_cell(rng):
    """Bisector rows of a robot among neighbours 0.5–3 m away, 1,000 m from the origin,
    less a buffer of 0.2–0.4 m; the target 2,000 m away."""
    p = _unit(rng, 1)[0] * 1000.0
    neighbours = p + _unit(rng, ROWS) * rng.uniform(0.5, 3.0, (ROWS, 1))
    A = (neighbours - p) / np.linalg.norm(neighbours - p, axis=-1, keepdims=True)
    b = np.einsum("ij,ij->i", A, (neighbours + p) / 2) - rng.uniform(0.2, 0.4, ROWS)
    return A, b, p + _unit(rng, 1)[0] * 2000.0


MAKERS = (concurrent_cell, parallel_cell, tiny_cell, bvc_like_cell)


def degenerate_cells(seed: int, n: int):
    """``n`` cells of the kinds above, some rows left out, with their targets and estimates."""
    rng = np.random.default_rng(seed)
    A, b = np.zeros((n, ROWS, 2)), np.ones((n, ROWS))
    valid = np.ones((n, ROWS), np.bool_)
    targets, estimates = np.empty((n, 2)), np.empty((n, 2))
    for i in range(n):
        a_i, b_i, targets[i] = MAKERS[i % len(MAKERS)](rng)
        valid[i] = rng.random(ROWS) < 0.9
        order = rng.permutation(ROWS)
        A[i] = np.where(valid[i, :, None], a_i[order], 0.0)
        b[i] = np.where(valid[i], b_i[order], 1.0)
        estimates[i] = targets[i] - _unit(rng, 1)[0] * rng.uniform(0.0, 5.0)
    kind = np.where(valid, int(Kind.ROBOT), -1).astype(np.int8)
    return Cells(A, b, valid, kind, np.zeros((n, ROWS), np.intp)), targets, estimates


def assert_exact(proj, goals, cells, robots):
    """Each robot's result equals the enumeration bit for bit and is the closest point of
    its cell (a brute-force optimum) up to the tolerance: both accept points within 1e-9
    of a row, which near rows meeting at a sharp angle, or at one point, moves the closest
    accepted point by a few times that (1e-8 allowed, relative to the scale)."""
    A_, b_, valid_ = cells.A.tolist(), cells.b.tolist(), cells.valid.tolist()
    for i in robots:
        x0, x1, k0, k1, empty = enumeration(float(goals[i, 0]), float(goals[i, 1]), A_[i], b_[i], valid_[i])
        assert np.array([x0, x1]).tobytes() == proj.point[i].tobytes(), i
        assert (k0, k1, empty) == (proj.active[i, 0], proj.active[i, 1], proj.empty[i]), i
        A, b = cells.robot(i)
        best = brute_force(goals[i], A, b)
        if best is None or empty:
            continue
        scale = 1.0 + np.linalg.norm(best - goals[i]) + np.abs(best).max()
        assert np.linalg.norm(proj.point[i] - goals[i]) <= np.linalg.norm(best - goals[i]) + 1e-8 * scale, i
        assert np.all(A @ proj.point[i] <= b + 1e-8 * scale), i


def test_projection_of_degenerate_cells_is_the_enumeration_and_the_closest_point():
    cells, targets, _ = degenerate_cells(seed=3, n=2000)
    proj = project_onto_cells(targets, cells)
    assert_exact(proj, targets, cells, range(len(targets)))
    assert proj.empty.any() and (proj.active[:, 1] >= 0).sum() > 300 and (proj.active[:, 0] < 0).sum() > 100


def test_both_projections_of_the_right_hand_stage_on_degenerate_cells():
    """The first projection of every target and the second of the blocked robots' turned
    targets (:func:`turned_projection`) are each the exact projection."""
    cells, targets, estimates = degenerate_cells(seed=4, n=2000)
    params = RightHandParams(angle=45.0, face_near=5.0)
    driving = np.random.default_rng(5).random(len(targets)) < 0.9
    proj = turned_projection(estimates, targets, cells, driving, params)
    first = project_onto_cells(targets, cells)
    turned = driving & ~first.empty & blocked_by_robot(estimates, first.active, cells, params.face_near)
    goals = targets.copy()
    rows = np.flatnonzero(turned)
    goals[rows] = right_hand_goals(estimates, targets, np.deg2rad(params.angle), rows)
    second = project_onto_cells(goals, cells)
    kept = turned & ~second.empty
    assert 200 < kept.sum() < len(targets)
    assert_exact(proj, goals, cells, np.flatnonzero(kept))
    assert_exact(proj, targets, cells, np.flatnonzero(~kept & ~first.empty))
