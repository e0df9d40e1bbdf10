"""Sensing and communication ranges of the robots (Section 2, Assumptions 2.3–2.5, 3.1.1).

All ranges are circular (Assumption 2.3):

* ``r_so`` — obstacle sensing (sonars). Standing on ``v``, a robot judges the edge to a
  neighbour blocked when the blocking obstacle lies within ``r_so`` (step 2). With
  Assumption 2.4 (``r_so ≥ a + r_safe``) every blockage of an edge is sensed; with a
  shorter range a blocked edge may look free and the robot bumps into the obstacle.
* ``r_st`` — target sensing (laser): a target at distance ``≤ r_st`` is detected.
* ``r_c`` — communication: robots within ``r_c`` are communication neighbours ``N_c,i(k)``.

Ranges are sensed through obstacles (the paper models range only, no occlusion).
Everything is precomputed per vertex, so a robot's sensing in the loop is a table row
look-up at its own vertex.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .grids import EPS, Grid


@dataclass(frozen=True, eq=False)
class SensingTables:
    """Per-vertex sensing results (O(V · (k + T)) memory).

    Attributes
    ----------
    edge_sensed_ok:
        ``(V, k)`` bool — what a robot on ``v`` believes about its edges: free
        unless a blockage was sensed within ``r_so`` (missing lattice neighbours are never
        options). Its true entries are also the neighbours step 2 records as discovered.
    target_visible:
        ``(V, T)`` bool — target ``t`` is within ``r_st`` of vertex ``v``.
    sensed_inaccessible:
        ``(V, k)`` bool — the lattice neighbours a robot on ``v`` senses inaccessible (a
        sensed blockage and the neighbour's clearance below ``r_safe``): step 2 records them
        as blocked (and as visited in situation 2).
    exact:
        the sensed edge states equal the true ones everywhere (Assumption 2.4 in effect).
    wall_push:
        ``(V, 2)`` repulsion of the sensed blocked edges, ``Σ −e_k / a`` (used by LFP).
    """

    edge_sensed_ok: np.ndarray
    target_visible: np.ndarray
    sensed_inaccessible: np.ndarray
    exact: bool
    wall_push: np.ndarray


def build_sensing(grid: Grid, targets: np.ndarray, r_so: float, r_st: float) -> SensingTables:
    """Precompute what a robot senses on every vertex (O(V·k + V·T))."""
    exists = grid.neighbours >= 0
    sensed_blocked = grid.block_distance <= r_so + EPS
    edge_sensed_ok = exists & ~sensed_blocked
    targets = np.asarray(targets, dtype=float).reshape(-1, 2)
    d = np.linalg.norm(grid.points[:, None, :] - targets[None, :, :], axis=-1)
    inaccessible = exists & sensed_blocked & ~grid.accessible[grid.candidates]
    return SensingTables(
        edge_sensed_ok,
        d <= r_st + EPS,
        inaccessible,
        bool(np.array_equal(edge_sensed_ok, grid.edge_ok)),
        np.where((exists & ~edge_sensed_ok)[:, :, None], -grid.edge_units, 0.0).sum(axis=1) / grid.a,
    )
