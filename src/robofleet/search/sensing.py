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
    """Per-vertex sensing results.

    Attributes
    ----------
    edge_sensed_ok:
        ``(V, k)`` bool — what a robot on ``v`` believes about its edges: free
        unless a blockage was sensed within ``r_so`` (missing lattice neighbours are never
        options).
    target_visible:
        ``(V, T)`` bool — target ``t`` is within ``r_st`` of vertex ``v``.
    self_bits, free_bits, inaccessible_bits:
        ``(V, W)`` uint64 bit rows (see :mod:`~robofleet.search.knowledge`) of the vertex
        itself, of the neighbours a robot on it senses reachable, and of the neighbours it
        senses inaccessible — what step 2 adds to its map.
    exact:
        the sensed edge states equal the true ones everywhere (Assumption 2.4 in effect).
    wall_push:
        ``(V, 2)`` repulsion of the sensed blocked edges, ``Σ −e_k / a`` (used by LFP).
    """

    edge_sensed_ok: np.ndarray
    target_visible: np.ndarray
    self_bits: np.ndarray
    free_bits: np.ndarray
    inaccessible_bits: np.ndarray
    exact: bool
    wall_push: np.ndarray

    def step2_rows(self, situation: int) -> np.ndarray:
        """``(V, 4, W)``: what step 2 adds to the visited / discovered / blocked / sensed layers
        of a robot standing on each vertex (situation 2 also records inaccessible neighbours
        as visited)."""
        visited = self.self_bits | self.inaccessible_bits if situation == 2 else self.self_bits
        return np.stack([visited, self.free_bits, self.inaccessible_bits, self.self_bits], axis=1)


def build_sensing(grid: Grid, targets: np.ndarray, r_so: float, r_st: float) -> SensingTables:
    """Precompute what a robot senses on every vertex (O(V·k + V·T))."""
    exists = grid.neighbours >= 0
    sensed_blocked = grid.block_distance <= r_so + EPS
    edge_sensed_ok = exists & ~sensed_blocked
    targets = np.asarray(targets, dtype=float).reshape(-1, 2)
    d = np.linalg.norm(grid.points[:, None, :] - targets[None, :, :], axis=-1)
    nb = np.maximum(grid.neighbours, 0)
    inaccessible = exists & sensed_blocked & ~grid.accessible[nb]
    ids = np.arange(grid.n_vertices)
    return SensingTables(
        edge_sensed_ok,
        d <= r_st + EPS,
        vertex_bit_rows(grid.n_vertices, ids[:, None], np.ones((grid.n_vertices, 1), dtype=bool)),
        vertex_bit_rows(grid.n_vertices, nb, edge_sensed_ok),
        vertex_bit_rows(grid.n_vertices, nb, inaccessible),
        bool(np.array_equal(edge_sensed_ok, grid.edge_ok)),
        np.where((exists & ~edge_sensed_ok)[:, :, None], -grid.edge_units, 0.0).sum(axis=1) / grid.a,
    )


def vertex_bit_rows(n_vertices: int, members: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``(V, W)`` uint64: row ``v`` has the bits of ``members[v][mask[v]]`` set."""
    rows = np.zeros((len(members), bit_words(n_vertices)), dtype=np.uint64)
    src, slot = np.nonzero(mask)
    ids = members[src, slot]
    np.bitwise_or.at(rows, (src, ids >> 6), np.uint64(1) << (ids & 63).astype(np.uint64))
    return rows


def bit_words(n_vertices: int) -> int:
    """Number of 64-bit words of a vertex bit set."""
    return -(-n_vertices // 64)
