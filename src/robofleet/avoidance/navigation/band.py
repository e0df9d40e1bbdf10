"""Band-return stage: a robot deep in the band its cells keep clear of an obstacle steers
back into its cell first (docs/theory/buavc.md "Navigation stages").

The cells keep an estimate ``β + r_ε σ_o`` away from an obstacle (r_s, the chance buffer
and the ε-shadow); noise puts the estimate outside its own cell in a share of the steps,
and a robot squeezed against an obstacle by a crowd can drift into that band, where the
paper's bound on the contact probability does not hold (its premise, the estimate in its
cell, fails). A robot whose estimate lies more than ``depth = sigmas · σ`` beyond one of
its cell's obstacle faces, ``(aₖ·p̂ − bₖ)/‖aₖ‖ > depth``, steers to its cell's point
nearest its estimate, ``Π_Vi(p̂)``, instead of to its projected target.

What the stage guarantees: the new target is a point of the robot's own cell (an exact
projection), so the next position stays in the cell; robots with an empty cell keep their
target. Steering back whenever the estimate is outside the cell at all would stop
progress (noise alone puts it outside in a sixth of the steps), hence the depth. Measured
effects: docs/results/avoidance.md "Measurements behind the navigation stages".
"""

from __future__ import annotations

import numba
import numpy as np

from ..cell import Cells, Kind, face_excess
from ..kernels import use_parallel
from ..projection import Projection, project_rows_into
from .params import BandParams

_OBSTACLE = int(Kind.OBSTACLE)
_CHUNK = 1024  # robots per parallel task


def out_of_the_band(estimates: np.ndarray, proj: Projection, cells: Cells, depth: float) -> Projection:
    """``proj`` with the target of every robot whose estimate lies more than ``depth``
    beyond one of its cell's obstacle faces replaced by ``Π_Vi(p̂)`` (module docstring)."""
    estimates = np.ascontiguousarray(estimates, dtype=np.float64)
    n = len(estimates)
    deep = np.empty(n, np.bool_)
    args = (estimates, np.ascontiguousarray(cells.A), np.ascontiguousarray(cells.b), np.ascontiguousarray(cells.valid),
            np.ascontiguousarray(cells.kind), np.ascontiguousarray(proj.empty), float(depth), deep)
    if use_parallel(n):
        _deep_parallel(*args)
    else:
        _deep_range(0, n, *args)
    idx = np.flatnonzero(deep)
    if len(idx) == 0:
        return proj
    point = proj.point.copy()
    project_rows_into(point, None, idx, estimates[idx], cells)
    return Projection(point, proj.empty, proj.active)


@numba.njit(cache=True, parallel=True)
def _deep_parallel(estimates, A, b, valid, kind, empty, depth, deep):
    n = len(estimates)
    for c in numba.prange((n + _CHUNK - 1) // _CHUNK):
        _deep_range(c * _CHUNK, min(n, (c + 1) * _CHUNK), estimates, A, b, valid, kind, empty, depth, deep)


@numba.njit(cache=True)
def _deep_range(lo, hi, estimates, A, b, valid, kind, empty, depth, deep):
    """Robots ``lo … hi − 1`` with a non-empty cell whose estimate lies more than ``depth``
    beyond one of its valid obstacle faces (:func:`~robofleet.avoidance.cell.face_excess` ``> depth``)."""
    for i in range(lo, hi):
        found = False
        if not empty[i]:
            for k in range(A.shape[1]):
                if not valid[i, k] or kind[i, k] != _OBSTACLE:
                    continue
                found |= face_excess(A, b, i, k, estimates[i, 0], estimates[i, 1]) > depth
        deep[i] = found
