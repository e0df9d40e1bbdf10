"""Exact Euclidean projection of each robot's goal onto its cell (2D, closed form).

For ``min ‖x − g‖²  s.t.  A x ≤ b`` in the plane, the optimum is ``g`` itself, the
projection of ``g`` onto one constraint line, or the intersection of two lines. KKT
narrows the candidates: if ``x* − g = −Σ λ_m a_m`` with ``λ ≥ 0`` and ``‖a_m‖ = 1``, then
``‖g − x*‖² = Σ λ_m (a_mᵀg − b_m) > 0``, so at least one active constraint is violated at
``g``. Hence we only examine edges of violated constraints and vertices pairing a
violated constraint with any other, and keep the closest feasible candidate. This is
exact (it enumerates every possible optimum) and costs O(V·M²) per robot for V violated
of M constraints, vectorized over robots in chunks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cell import Cells

FEAS_TOL = 1e-9
_CHUNK_ELEMS = 2_000_000


@dataclass(frozen=True)
class Projection:
    """Result of :func:`project_onto_cells`.

    point: ``(N, 2)`` closest point of each cell to the goal (the goal if inside; NaN if empty).
    empty: ``(N,)`` the cell has no point (the robot then stays put).
    active: ``(N, 2)`` indices into the cell's constraint rows that are active at ``point``
    (``-1`` where fewer than two are).
    """

    point: np.ndarray
    empty: np.ndarray
    active: np.ndarray


def project_onto_cells(goals: np.ndarray, cells: Cells) -> Projection:
    """Project ``goals (N, 2)`` onto the cells (exact; see module docstring)."""
    n = len(goals)
    A, b, valid = cells.A, cells.b, cells.valid
    slack = np.einsum("nmd,nd->nm", A, goals) - b
    violated = (slack > FEAS_TOL) & valid
    point = goals.astype(float).copy()
    empty = np.zeros(n, bool)
    active = np.full((n, 2), -1, np.intp)
    todo = np.flatnonzero(violated.any(axis=1))
    if len(todo) == 0:
        return Projection(point, empty, active)
    n_viol = violated[todo].sum(axis=1)
    v = int(n_viol.max())
    m = A.shape[1]
    step = max(1, _CHUNK_ELEMS // max(1, v * m * m))
    for start in range(0, len(todo), step):
        rows = todo[start:start + step]
        x, ok, act = _project_rows(goals[rows], A[rows], b[rows], valid[rows], slack[rows], violated[rows], v)
        point[rows], empty[rows], active[rows] = x, ~ok, act
    return Projection(point, empty, active)


def _project_rows(g, A, b, valid, slack, violated, v):
    s, m = violated.shape
    # indices of the (up to v) most violated constraints, padded with -1
    order = np.argsort(np.where(violated, -slack, np.inf), axis=1)[:, :v]
    has = np.take_along_axis(violated, order, axis=1)
    av = np.take_along_axis(A, order[..., None], axis=1)          # (S, v, 2)
    sv = np.take_along_axis(slack, order, axis=1)                  # (S, v)
    # edge candidates: projection onto each violated line
    edge = g[:, None] - sv[..., None] * av                         # (S, v, 2)
    edge_ok = has & _feasible(edge, A, b, valid)
    edge_d = np.where(edge_ok, np.abs(sv), np.inf)
    # vertex candidates: violated line k ∩ any line m
    bv = np.take_along_axis(b, order, axis=1)
    det = av[:, :, None, 0] * A[:, None, :, 1] - av[:, :, None, 1] * A[:, None, :, 0]   # (S, v, M)
    good = has[:, :, None] & valid[:, None, :] & (np.abs(det) > 1e-12) & (order[:, :, None] != np.arange(m)[None, None])
    safe = np.where(good, det, 1.0)
    x0 = (bv[:, :, None] * A[:, None, :, 1] - b[:, None, :] * av[:, :, None, 1]) / safe
    x1 = (av[:, :, None, 0] * b[:, None, :] - A[:, None, :, 0] * bv[:, :, None]) / safe
    vert = np.stack([x0, x1], axis=-1)                              # (S, v, M, 2)
    vert_ok = good & _feasible(vert.reshape(s, v * m, 2), A, b, valid).reshape(s, v, m)
    vert_d = np.where(vert_ok, np.linalg.norm(vert - g[:, None, None], axis=-1), np.inf)
    # choose the closest feasible candidate
    e_best = np.argmin(edge_d, axis=1)
    v_flat = vert_d.reshape(s, -1)
    v_best = np.argmin(v_flat, axis=1)
    e_val = edge_d[np.arange(s), e_best]
    v_val = v_flat[np.arange(s), v_best]
    use_edge = e_val <= v_val
    r = np.arange(s)
    vk, vm = np.unravel_index(v_best, (v, m))
    x = np.where(use_edge[:, None], edge[r, e_best], vert[r, vk, vm])
    act = np.where(use_edge[:, None], np.stack([order[r, e_best], np.full(s, -1)], 1), np.stack([order[r, vk], vm], 1))
    ok = np.isfinite(np.minimum(e_val, v_val))
    x = np.where(ok[:, None], x, np.nan)
    act = np.where(ok[:, None], act, -1)
    return x, ok, act


def _feasible(points, A, b, valid):
    """``points (S, K, 2)`` each inside its robot's cell ``(S, M, 2)``."""
    lhs = np.einsum("skd,smd->skm", points, A)
    return np.all((lhs <= b[:, None] + FEAS_TOL) | ~valid[:, None], axis=-1)
