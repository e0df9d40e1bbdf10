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

import numpy as np

from ..cell import Cells, Kind, cell_rows
from ..projection import Projection, project_onto_cells
from .params import BandParams


def out_of_the_band(estimates: np.ndarray, proj: Projection, cells: Cells, depth: float) -> Projection:
    """``proj`` with the target of every robot whose estimate lies more than ``depth``
    beyond one of its cell's obstacle faces replaced by ``Π_Vi(p̂)`` (module docstring)."""
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
