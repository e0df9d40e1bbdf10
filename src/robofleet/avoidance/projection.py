"""Exact Euclidean projection of each robot's goal onto its cell (2D, closed form).

``min ‖x − g‖²  s.t.  a_mᵀx ≤ b_m`` (``‖a_m‖ = 1``). The optimum is ``g`` itself, the
projection onto one constraint line, or the intersection of two lines, and KKT narrows
the candidates (``x* = g − Σ λ_m a_m``, ``λ ≥ 0``):

1. An active constraint is violated at ``g`` (``‖g − x*‖² = Σ λ_m (a_mᵀg − b_m) > 0``).
2. Edge candidates: the projection ``x_m`` of ``g`` onto a violated half-plane ``m`` is the
   optimum over that half-plane, a superset of the cell; if ``x_m`` is feasible it is
   therefore optimal.
3. Otherwise the optimum is a vertex ``v`` of lines ``(m, k)``, ``m`` violated, whose
   multipliers solve ``[a_m a_k] λ = g − v`` with ``λ ≥ 0``; such a ``v`` is the optimum of
   the two-constraint relaxation, so if it is feasible it is optimal.

Candidates are kept as flat lists (one row per robot × candidate), so the work is
O(C · M) for C candidates instead of O(N · M³); feasibility is tested to ``FEAS_TOL``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cell import Cells

FEAS_TOL = 1e-9


@dataclass(frozen=True)
class Projection:
    """Result of :func:`project_onto_cells`.

    point: ``(N, 2)`` closest point of each cell to the goal (the goal if inside; NaN if empty).
    empty: ``(N,)`` the cell has no point (the robot then stays put).
    active: ``(N, 2)`` constraint rows active at ``point`` (``-1`` where fewer than two are).
    """

    point: np.ndarray
    empty: np.ndarray
    active: np.ndarray


def project_onto_cells(goals: np.ndarray, cells: Cells) -> Projection:
    """Project ``goals (N, 2)`` onto the cells (exact; see module docstring)."""
    A, b, valid = cells.A, cells.b, cells.valid
    slack = _dot(A, goals[:, None]) - b
    violated = (slack > FEAS_TOL) & valid
    point = goals.astype(float).copy()
    active = np.full((len(goals), 2), -1, np.intp)
    robot, row = np.nonzero(violated)
    if len(robot) == 0:
        return Projection(point, np.zeros(len(goals), bool), active)
    # 2. edge candidates
    cand = goals[robot] - slack[robot, row, None] * A[robot, row]
    ok = _feasible(cand, robot, cells)
    solved = _pick(robot, ok, slack[robot, row], len(goals))
    has_edge = solved >= 0
    point[has_edge] = cand[solved[has_edge]]
    active[has_edge, 0] = row[solved[has_edge]]
    # 3. vertex candidates for the rest
    rest = np.flatnonzero(violated.any(axis=1) & ~has_edge)
    empty = np.zeros(len(goals), bool)
    if len(rest):
        _vertex_step(goals, cells, violated, rest, point, active, empty)
    return Projection(point, empty, active)


def _vertex_step(goals, cells: Cells, violated, rest, point, active, empty):
    A, b, valid = cells.A, cells.b, cells.valid
    m_count = A.shape[1]
    sub_viol = violated[rest]
    r_idx, m_idx = np.nonzero(sub_viol)
    # pair every violated row m of a robot with every other valid row k of that robot
    k_idx = np.tile(np.arange(m_count), len(r_idx))
    r_rep, m_rep = np.repeat(r_idx, m_count), np.repeat(m_idx, m_count)
    robot = rest[r_rep]
    keep = valid[robot, k_idx] & (k_idx != m_rep)
    robot, m_rep, k_idx = robot[keep], m_rep[keep], k_idx[keep]
    am, ak = A[robot, m_rep], A[robot, k_idx]
    bm, bk = b[robot, m_rep], b[robot, k_idx]
    det = am[:, 0] * ak[:, 1] - am[:, 1] * ak[:, 0]
    good = np.abs(det) > 1e-12
    det = np.where(good, det, 1.0)
    vert = np.column_stack([(bm * ak[:, 1] - bk * am[:, 1]) / det, (am[:, 0] * bk - ak[:, 0] * bm) / det])
    resid = goals[robot] - vert  # = λ_m a_m + λ_k a_k
    lam_m = (resid[:, 0] * ak[:, 1] - resid[:, 1] * ak[:, 0]) / det
    lam_k = (am[:, 0] * resid[:, 1] - am[:, 1] * resid[:, 0]) / det
    good &= (lam_m >= -FEAS_TOL) & (lam_k >= -FEAS_TOL)
    robot, vert, m_rep, k_idx = robot[good], vert[good], m_rep[good], k_idx[good]
    ok = _feasible(vert, robot, cells) if len(robot) else np.zeros(0, bool)
    dist = np.linalg.norm(vert - goals[robot], axis=1)
    solved = _pick(robot, ok, dist, len(goals))
    found = solved[rest] >= 0
    got = rest[found]
    point[got] = vert[solved[got]]
    active[got] = np.column_stack([m_rep[solved[got]], k_idx[solved[got]]])
    none = rest[~found]
    point[none] = np.nan
    empty[none] = True


def _pick(robot: np.ndarray, ok: np.ndarray, cost: np.ndarray, n: int) -> np.ndarray:
    """Per robot, the index of its feasible candidate of least cost (``-1`` if none)."""
    out = np.full(n, -1, np.intp)
    idx = np.flatnonzero(ok)
    if len(idx):
        order = idx[np.lexsort((cost[idx], robot[idx]))]
        first = np.unique(robot[order], return_index=True)[1]
        out[robot[order[first]]] = order[first]
    return out


def _feasible(points: np.ndarray, robot: np.ndarray, cells: Cells) -> np.ndarray:
    """Whether candidate ``points (C, 2)`` lie in the cells of their ``robot (C,)``."""
    lhs = _dot(cells.A[robot], points[:, None])
    return np.all((lhs <= cells.b[robot] + FEAS_TOL) | ~cells.valid[robot], axis=1)


def _dot(A: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``A[..., 0] p[..., 0] + A[..., 1] p[..., 1]`` (faster than einsum for d = 2)."""
    return A[..., 0] * p[..., 0] + A[..., 1] * p[..., 1]
