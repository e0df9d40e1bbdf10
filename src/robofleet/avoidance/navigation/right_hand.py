"""Right-hand rule stage: a robot blocked by a neighbour's face veers right
(docs/theory/buavc.md "Navigation stages"; Zhou et al., RA-L 2017, for BVC).

A driving robot whose projected target lies on a face shared with a neighbour
(:attr:`~robofleet.avoidance.cell.Kind.ROBOT`), within ``face_near`` of its estimate
(:func:`blocked_by_robot`), turns its target clockwise about its estimate by ``angle``:
``t' = R_z(−angle)(t − p̂) + p̂`` (:func:`right_hand_goals`). As every robot veers the
same way, head-on pairs pass and crowds that meet at one point circulate as in a
roundabout.

Two forms, by where the stage sits in a model's pipeline
(:mod:`~robofleet.avoidance.navigation.pipeline`):

* :func:`turned_projection` (with the projection, single integrators): the blocked
  robots' turned targets are projected onto their cells again; a robot keeps its first
  projection when the turned one is empty.
* :func:`turned_targets` (before the model's own controller projects, double
  integrators): the target is turned unless the turned target projects onto an
  obstacle's face (in a lane between an obstacle on its right and a neighbour on its
  left the turn would drive the robot into the obstacle and stop it there).

What the stage guarantees: it only changes the target; the projection, or the model's
cell-keeping controller, keeps the next position inside the cell. Not for unicycles
(their three-projection controller drives the turned arcs into the walls). Measured
effects: docs/results/avoidance.md "Measurements behind the navigation stages".
"""

from __future__ import annotations

import numba
import numpy as np

from ..cell import Cells, Kind, face_excess
from ..kernels import row_products, use_parallel
from ..projection import EVERY_ROBOT, Projection, check_projection_inputs, project_onto_cells, project_rows_into, project_span
from .params import RightHandParams


_ROBOT = int(Kind.ROBOT)
_CHUNK = 1024  # robots per parallel task


def blocked_by_robot(estimates: np.ndarray, active: np.ndarray, cells, near: float) -> np.ndarray:
    """``(N,)``: an active constraint at the projected goal is a face shared with a
    neighbour (:attr:`Kind.ROBOT`) and the robot's estimate lies within ``near`` of it,
    ``(bₖ − aₖ·p̂)/‖aₖ‖ < near`` (one compiled pass over the robots)."""
    n = len(estimates)
    out = np.empty(n, np.bool_)
    args = (np.ascontiguousarray(estimates, dtype=np.float64), np.ascontiguousarray(active), np.ascontiguousarray(cells.A),
            np.ascontiguousarray(cells.b), np.ascontiguousarray(cells.kind), float(near), out)
    if use_parallel(n):
        _blocked_parallel(*args)
    else:
        _blocked_range(0, n, *args)
    return out


@numba.njit(cache=True, parallel=True)
def _blocked_parallel(estimates, active, A, b, kind, near, out):
    n = len(estimates)
    for c in numba.prange((n + _CHUNK - 1) // _CHUNK):
        _blocked_range(c * _CHUNK, min(n, (c + 1) * _CHUNK), estimates, active, A, b, kind, near, out)


@numba.njit(cache=True)
def _blocked_range(lo, hi, estimates, active, A, b, kind, near, out):
    """:func:`blocked_by_robot` for robots ``lo … hi − 1``."""
    for i in range(lo, hi):
        out[i] = _blocked(i, estimates, active, A, b, kind, near)


@numba.njit(cache=True, inline="always")
def _blocked(i, estimates, active, A, b, kind, near):
    """Robot ``i`` is blocked (:func:`blocked_by_robot`): the gap ``(bₖ − aₖ·p̂)/‖aₖ‖`` is
    exactly ``−``:func:`~robofleet.avoidance.cell.face_excess` (``x − y = −(y − x)`` in
    floating point)."""
    blocked = False
    for c in range(active.shape[1]):
        k = active[i, c]
        if k < 0 or kind[i, k] != _ROBOT:
            continue
        blocked |= -face_excess(A, b, i, k, estimates[i, 0], estimates[i, 1]) < near
    return blocked


def right_hand_goals(estimates: np.ndarray, goals: np.ndarray, angle: float, rows: np.ndarray | None = None) -> np.ndarray:
    """The goals turned clockwise by ``angle`` [rad] about each robot, ``(g − p̂) Rᵀ + p̂``;
    with ``rows``, those of the robots ``rows`` only, ``(R, 2)``: the values for
    ``goals[rows]`` and ``estimates[rows]`` (one product of those rows: a row of a product
    may round differently with other rows around it), with the differences and sums taken
    in one compiled pass each instead of gathering the rows."""
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, s], [-s, c]])
    if rows is None:
        return row_products(goals - estimates, turn.T) + estimates
    estimates = np.ascontiguousarray(estimates, dtype=np.float64)
    offsets = np.empty((len(rows), 2))
    _row_offsets(rows, np.ascontiguousarray(goals, dtype=np.float64), estimates, offsets)
    turned = row_products(offsets, turn.T)
    _add_rows(turned, rows, estimates)
    return turned


@numba.njit(cache=True)
def _row_offsets(rows, goals, estimates, out):
    """``out[r] = goals[rows[r]] − estimates[rows[r]]``."""
    for r in range(len(rows)):
        i = rows[r]
        out[r, 0], out[r, 1] = goals[i, 0] - estimates[i, 0], goals[i, 1] - estimates[i, 1]


@numba.njit(cache=True)
def _add_rows(out, rows, estimates):
    """``out[r] += estimates[rows[r]]``."""
    for r in range(len(rows)):
        i = rows[r]
        out[r, 0], out[r, 1] = out[r, 0] + estimates[i, 0], out[r, 1] + estimates[i, 1]


def on_obstacle_face(active: np.ndarray, cells) -> np.ndarray:
    """``(N,)``: an active constraint of the projection is an obstacle's face."""
    rows = np.arange(len(active))[:, None]
    return np.any((active >= 0) & (cells.kind[rows, np.maximum(active, 0)] == Kind.OBSTACLE), axis=1)


def turned_projection(estimates: np.ndarray, targets: np.ndarray, cells: Cells, driving: np.ndarray,
                      params: RightHandParams) -> Projection:
    """Every target projected onto its cell (:func:`~robofleet.avoidance.projection.project_onto_cells`),
    and the blocked ``driving`` robots' (:func:`blocked_by_robot` on that projection)
    turned right and projected again, unless the turned projection is empty. One compiled
    pass projects and finds the blocked robots; only their rows are then turned
    (:func:`right_hand_goals`) and projected again, in place
    (:func:`~robofleet.avoidance.projection.project_rows_into`)."""
    check_projection_inputs(targets, cells)
    n = len(targets)
    estimates = np.ascontiguousarray(estimates, dtype=np.float64)
    point, empty, active, turn = np.empty((n, 2)), np.empty(n, np.bool_), np.empty((n, 2), np.intp), np.empty(n, np.bool_)  # every row written
    args = (np.ascontiguousarray(targets, dtype=np.float64), estimates, np.ascontiguousarray(cells.A), np.ascontiguousarray(cells.b),
            np.ascontiguousarray(cells.valid), np.ascontiguousarray(cells.kind), np.ascontiguousarray(driving, dtype=np.bool_),
            float(params.face_near), point, empty, active, turn)
    if use_parallel(n):
        _projected_parallel(*args)
    else:
        _projected_range(0, n, *args)
    rows = np.flatnonzero(turn)
    if len(rows):
        project_rows_into(point, active, rows, right_hand_goals(estimates, targets, np.deg2rad(params.angle), rows), cells)
    return Projection(point, empty, active)


@numba.njit(cache=True, parallel=True)
def _projected_parallel(targets, estimates, A, b, valid, kind, driving, near, point, empty, active, turn):
    n = len(targets)
    for c in numba.prange((n + _CHUNK - 1) // _CHUNK):
        _projected_range(c * _CHUNK, min(n, (c + 1) * _CHUNK), targets, estimates, A, b, valid, kind, driving, near, point, empty, active,
                         turn)


@numba.njit(cache=True)
def _projected_range(lo, hi, targets, estimates, A, b, valid, kind, driving, near, point, empty, active, turn):
    """Robots ``lo … hi − 1``: each target's projection, and whether the robot turns
    (driving, a non-empty cell, blocked)."""
    project_span(lo, hi, EVERY_ROBOT, targets, A, b, valid, point, empty, active, False, True)
    for i in range(lo, hi):
        turn[i] = driving[i] and not empty[i] and _blocked(i, estimates, active, A, b, kind, near)


def turned_targets(estimates: np.ndarray, targets: np.ndarray, cells: Cells, driving: np.ndarray,
                   params: RightHandParams) -> np.ndarray:
    """The targets of the blocked ``driving`` robots turned right, unless the turned target
    projects onto an obstacle's face."""
    proj = project_onto_cells(targets, cells)
    turn = driving & ~proj.empty & blocked_by_robot(estimates, proj.active, cells, params.face_near)
    if params.angle <= 0 or not turn.any():
        return targets
    turned = right_hand_goals(estimates, targets, np.deg2rad(params.angle))
    turn &= ~on_obstacle_face(project_onto_cells(turned, cells).active, cells)
    return np.where(turn[:, None], turned, targets)
