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
4. No candidate is feasible only when the cell is empty.

Each robot's problem has a handful of constraints and data-dependent branches, so the
kernel is compiled with numba (a flat-list numpy version of the same enumeration spent
~15 passes over arrays of all candidates and was the hot spot of the 10,000-robot step;
see ``benchmarks/avoidance_scale.py``), robots in parallel (:mod:`.kernels`), in one flat
loop (:func:`project_span`) that first gathers a cell's valid rows into contiguous work
arrays. Cost: O(V · M²) per robot for V violated of M constraints, typically V, M ≤ 6.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ..core.errors import ConfigError, short_repr
from .cell import Cells
from .kernels import use_parallel

FEAS_TOL = 1e-9
ROUNDING = 1e-14
"""A constraint ``aᵀx ≤ b`` counts as met when ``aᵀx − b ≤ FEAS_TOL + ROUNDING (|a_0 x_0| +
|a_1 x_1| + |b|)``: 1e-9 m, plus the rounding error of the candidate and of the test,
which only matters for points or offsets far beyond metres (goals 1e50 m away, buffers
of covariances of 1e300)."""


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
    check_projection_inputs(goals, cells)
    n = len(goals)
    point = np.empty((n, 2))
    empty = np.zeros(n, np.bool_)
    active = np.full((n, 2), -1, np.intp)
    args = (EVERY_ROBOT, np.ascontiguousarray(goals, dtype=np.float64), np.ascontiguousarray(cells.A), np.ascontiguousarray(cells.b),
            np.ascontiguousarray(cells.valid), point, empty, active, False, True)
    if use_parallel(n):
        _project_parallel(n, *args)
    else:
        project_span(0, n, *args)
    return Projection(point, empty, active)


EVERY_ROBOT = np.zeros(0, np.intp)
"""The ``robots`` of :func:`project_span` for every robot ``lo … hi − 1`` (goal ``i`` for robot ``i``)."""


@numba.njit(cache=True, inline="always")
def _excess(x0, x1, a0, a1, off, r):
    """How far ``x`` violates gathered row ``r`` beyond the tolerance (> 0: violated; see
    :data:`ROUNDING`)."""
    p0, p1 = a0[r] * x0, a1[r] * x1
    return p0 + p1 - off[r] - (FEAS_TOL + ROUNDING * (abs(p0) + abs(p1) + abs(off[r])))


@numba.njit(cache=True, inline="always")
def _feasible(x0, x1, a0, a1, off, count):
    """``x`` meets the gathered rows ``0 … count − 1`` (the cell's valid rows)."""
    for r in range(count):
        if _excess(x0, x1, a0, a1, off, r) > 0:
            return False
    return True


_CHUNK = 256  # robots per parallel task (one set of work arrays each)


@numba.njit(cache=True, parallel=True)
def _project_parallel(n, robots, goals, A, b, valid, point, empty, active, only_found, with_active):
    """:func:`project_span` of ``0 … n − 1`` in parallel chunks (robots are independent;
    ``robots`` must not repeat one)."""
    for c in numba.prange((n + _CHUNK - 1) // _CHUNK):
        project_span(c * _CHUNK, min(n, (c + 1) * _CHUNK), robots, goals, A, b, valid, point, empty, active, only_found, with_active)


@numba.njit(cache=True)
def project_span(lo, hi, robots, goals, A, b, valid, point, empty, active, only_found, with_active):
    """Steps 1–4 of the module docstring for the goals ``lo … hi − 1``: goal ``o`` onto the
    cell of robot ``robots[o]`` (robot ``o`` for :data:`EVERY_ROBOT`), its closest point
    written to ``point[i]``, its active rows to ``active[i]`` (when ``with_active``; ``-1``
    for an active row not used) and whether the cell is empty to ``empty[i]`` (the point
    then NaN) — or, with ``only_found``, the point and rows only for a non-empty cell and
    ``empty`` left alone.

    Each cell's valid rows are first gathered, in order, into work arrays, which the
    search then reads contiguously. Candidates are tried in the order of the rows, and one
    replaces the best so far only when it is feasible and strictly closer, so the first of
    equally close ones is kept. A vertex of two violated rows ``k < j`` is tried once, as
    ``(k, j)``: taken as ``(j, k)`` its determinant and numerators are the exact negations
    and its multipliers the same two numbers swapped (a difference of two products changes
    sign exactly when they swap), so it has the same distance and the same tests, and comes
    later, where it could not replace ``(k, j)``. One flat loop: the same search as a
    function returning each robot's result took 1.2 times as long
    (docs/results/avoidance.md)."""
    m = A.shape[1]
    a0, a1, off, slack, index = np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty(m, np.intp)
    violated = np.empty(m, np.bool_)
    every = len(robots) == 0
    for o in range(lo, hi):
        i = o if every else robots[o]
        g0, g1 = goals[o, 0], goals[o, 1]
        count, any_violated = 0, False
        for k in range(m):
            if valid[i, k]:
                a0[count], a1[count], off[count], index[count] = A[i, k, 0], A[i, k, 1], b[i, k], k
                slack[count] = a0[count] * g0 + a1[count] * g1 - off[count]
                violated[count] = _excess(g0, g1, a0, a1, off, count) > 0
                any_violated |= violated[count]
                count += 1
        x0, x1, k0, k1, none = g0, g1, -1, -1, False
        if any_violated:
            best = np.inf  # step 2: the feasible projection onto a violated row nearest g (best: its slack)
            for r in range(count):
                if violated[r]:
                    e0, e1 = g0 - slack[r] * a0[r], g1 - slack[r] * a1[r]
                    if slack[r] < best and _feasible(e0, e1, a0, a1, off, count):
                        best = slack[r]
                        x0, x1, k0, k1 = e0, e1, index[r], -1
            if best == np.inf:  # steps 3–4: the feasible vertex with λ ≥ 0 nearest g, or none
                x0, x1 = np.nan, np.nan
                for r in range(count):
                    if not violated[r]:
                        continue
                    ak0, ak1, bk = a0[r], a1[r], off[r]
                    for s in range(count):
                        if s == r or (violated[s] and s < r):  # (s, r) was tried as such
                            continue
                        aj0, aj1, bj = a0[s], a1[s], off[s]
                        det = ak0 * aj1 - ak1 * aj0
                        if abs(det) <= 1e-12:
                            continue
                        v0 = (bk * aj1 - bj * ak1) / det
                        v1 = (ak0 * bj - aj0 * bk) / det
                        r0, r1 = g0 - v0, g1 - v1
                        lam_k = (r0 * aj1 - r1 * aj0) / det
                        lam_j = (ak0 * r1 - ak1 * r0) / det
                        if lam_k < -FEAS_TOL or lam_j < -FEAS_TOL:
                            continue
                        dist = np.sqrt(r0 * r0 + r1 * r1)
                        if dist < best and _feasible(v0, v1, a0, a1, off, count):
                            best = dist
                            x0, x1, k0, k1 = v0, v1, index[r], index[s]
                none = best == np.inf
        if none and only_found:
            continue
        point[i, 0], point[i, 1] = x0, x1
        if with_active:
            active[i, 0], active[i, 1] = k0, k1
        if not only_found:
            empty[i] = none


def project_rows_into(point: np.ndarray, active: np.ndarray | None, rows: np.ndarray, goals: np.ndarray, cells: Cells) -> None:
    """Project ``goals[r]`` onto the cell of robot ``rows[r]`` and, unless that cell is
    empty, write the result into ``point[rows[r]]`` (and ``active[rows[r]]`` when
    ``active`` is given), in place: the values :func:`project_onto_cells` computes for
    ``goals`` and ``cell_rows(cells, rows)``, without gathering those rows' cells.
    ``rows`` must not repeat a robot."""
    rows = np.ascontiguousarray(rows, dtype=np.intp)
    if len(rows) == 0:
        return
    target = np.zeros((0, 2), np.intp) if active is None else active
    args = (rows, np.ascontiguousarray(goals, dtype=np.float64), np.ascontiguousarray(cells.A), np.ascontiguousarray(cells.b),
            np.ascontiguousarray(cells.valid), point, np.zeros(0, np.bool_), target, True, active is not None)
    if use_parallel(len(rows)):
        _project_parallel(len(rows), *args)
    else:
        project_span(0, len(rows), *args)


def steer(estimates: np.ndarray, proj: Projection, v_max: float | np.ndarray, dt: float, hold: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The one-step controller's command toward the projected goals (appendix C):
    ``u = min(v_max, ‖g* − p̂‖/Δt) · (g* − p̂)/‖g* − p̂‖``, zero for an empty cell, a
    distance under 1e-12 or a robot in ``hold``; one compiled pass, rounded as the numpy
    expressions ``np.where`` / ``np.linalg.norm`` / ``np.minimum`` would round it.

    Returns ``u (N, 2)``, its norm ``(N,)`` and the distance to the projected goal
    (``inf`` for an empty cell: the deadlock test's "sitting" input).
    """
    n = len(estimates)
    u, speed, move = np.empty((n, 2)), np.empty(n), np.empty(n)
    limit = np.ascontiguousarray(np.broadcast_to(np.asarray(v_max, dtype=np.float64), (n,)))
    args = (np.ascontiguousarray(estimates, dtype=np.float64), proj.point, proj.empty, limit, float(dt),
            np.ascontiguousarray(hold, dtype=np.bool_), u, speed, move)
    if use_parallel(n):
        _steer_parallel(*args)
    else:
        _steer_range(0, n, *args)
    return u, speed, move


@numba.njit(cache=True, parallel=True)
def _steer_parallel(estimates, point, empty, v_max, dt, hold, u, speed, move):
    n, chunk = len(estimates), 4 * _CHUNK
    for c in numba.prange((n + chunk - 1) // chunk):
        _steer_range(c * chunk, min(n, (c + 1) * chunk), estimates, point, empty, v_max, dt, hold, u, speed, move)


@numba.njit(cache=True)
def _steer_range(lo, hi, estimates, point, empty, v_max, dt, hold, u, speed, move):
    for i in range(lo, hi):
        if empty[i]:  # the target is the estimate itself: p̂ − p̂ = 0
            d0, d1 = estimates[i, 0] - estimates[i, 0], estimates[i, 1] - estimates[i, 1]
        else:
            d0, d1 = point[i, 0] - estimates[i, 0], point[i, 1] - estimates[i, 1]
        dist = np.sqrt(d0 * d0 + d1 * d1)
        limit, reach = v_max[i], dist / dt
        pace = limit if limit != limit else reach if reach != reach else min(limit, reach)  # np.minimum propagates NaN
        u0 = u1 = 0.0
        if dist > 1e-12 and not hold[i]:
            factor = pace / max(dist, 1e-300)
            u0, u1 = d0 * factor, d1 * factor
        u[i, 0], u[i, 1] = u0, u1
        speed[i] = np.sqrt(u0 * u0 + u1 * u1)
        move[i] = np.inf if empty[i] else dist


# -- input validation of project_onto_cells (types and shapes only: it runs every step) -------
def check_projection_inputs(goals: object, cells: object) -> None:
    """One-line :class:`~robofleet.core.errors.ConfigError` s for arguments of the wrong kind or shape."""
    if not isinstance(cells, Cells) or cells.A.ndim != 3 or cells.A.shape[-1] != 2:
        raise ConfigError(f"cells: expected planar Cells (build_cells of 2-D estimates), received {short_repr(cells)}")
    if np.shape(goals) != (cells.A.shape[0], 2):
        raise ConfigError(f"goals: expected an array ({cells.A.shape[0]}, 2), one goal per cell, received shape {np.shape(goals)}")
