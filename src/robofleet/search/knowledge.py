"""What each robot knows: its own topological map, and the messages that update it.

Section 1: "the map only includes the coordinates and visitation states of vertices".
Each robot ``i`` keeps, as rows of bit sets (one bit per vertex, 64 vertices per word):

* ``visited[i]``    — ``V_v,i``: vertices it knows to be visited (by itself, by the choices
  it received, by map exchange; in situation 2 also the vertices it sensed as blocked,
  step 2),
* ``discovered[i]`` — vertices it has seen as accessible neighbours of visited vertices
  (its map of the area so far; stop rule (4) asks for every discovered vertex visited),
* ``blocked[i]``    — vertices it knows to be blocked: sensed obstacles and the vertices
  of robots detected as failed (failure information, step 3),
* ``sensed[i]``     — vertices some robot stood on and sensed around, in its map: their
  neighbourhood is known. A vertex can be known as visited before that — a broadcast choice
  (step 5) marks the chosen vertex visited in the receivers' maps at once —, so stop rule
  (4) also waits for the neighbourhood of every visited vertex,
* ``targets[i]``    — ``T_k,i``: targets it knows.

Rows are only ever written by the robot itself (sensing, its choice) or by
:meth:`RobotMaps.exchange`, which ORs in the rows of its communication neighbours — the
explicit message passing of step 3. Nothing reads another robot's row directly.
"""

from __future__ import annotations

import numpy as np

ONE = np.uint64(1)
WORD = 64


class RobotMaps:
    """Per-robot knowledge of ``n_robots`` robots on a grid of ``n_vertices`` vertices."""

    def __init__(self, n_robots: int, n_vertices: int, n_targets: int):
        words = -(-n_vertices // WORD)
        self.n_vertices = n_vertices
        # layers: 0 visited, 1 discovered, 2 blocked, 3 sensed
        self.layers = np.zeros((n_robots, 4, words), dtype=np.uint64)
        self.targets = np.zeros((n_robots, n_targets), dtype=bool)

    # -- bit-set primitives -------------------------------------------------------------
    def test(self, layer: int, robots: np.ndarray, vertices: np.ndarray) -> np.ndarray:
        """Bits of ``layer`` for ``robots (m,)`` at ``vertices (m, k)`` (ids ≥ 0)."""
        words = self.layers[robots[:, None], layer, vertices >> 6]
        return ((words >> (vertices & 63).astype(np.uint64)) & ONE).astype(bool)

    def test_words(self, layer: int, robots: np.ndarray, words: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """Like :meth:`test` with the word indices and bit masks of the vertices precomputed."""
        return (self.layers[robots[:, None], layer, words] & masks) != 0

    def set(self, layer: int, robots: np.ndarray, vertices: np.ndarray) -> None:
        """Set the bits of ``layer`` for the pairs ``(robots[j], vertices[j])``."""
        robots = np.asarray(robots, dtype=np.intp).ravel()
        vertices = np.asarray(vertices, dtype=np.intp).ravel()
        if len(vertices):
            np.bitwise_or.at(self.layers, (robots, layer, vertices >> 6), ONE << (vertices & 63).astype(np.uint64))

    def as_bool(self, layer: int) -> np.ndarray:
        """``(n_robots, V)`` boolean view of one layer (for checks and plots, not hot paths)."""
        bits = np.unpackbits(self.layers[:, layer, :].view(np.uint8), axis=1, bitorder="little")
        return bits[:, : self.n_vertices].astype(bool)

    # -- messages -----------------------------------------------------------------------
    def exchange(self, links: np.ndarray) -> None:
        """Step 3: every robot ORs in the maps of its communication neighbours.

        ``links (R, n, n)`` bool, one block per independent run: ``links[r, i, j]`` when
        robot ``i`` receives robot ``j``'s message this step (``j ∈ N_c,i(k)``, both alive).
        One hop per step, as in the paper's temporary ad-hoc networks.
        """
        if not links.any():
            return
        runs, n = links.shape[0], links.shape[1]
        layers = self.layers.reshape(runs, n, *self.layers.shape[1:])
        merged = np.where(links[:, :, :, None, None], layers[:, None], np.uint64(0))
        layers |= np.bitwise_or.reduce(merged, axis=2)
        targets = self.targets.reshape(runs, n, -1)
        targets |= (links[:, :, :, None] & targets[:, None]).any(axis=2)

    def broadcast_targets(self, found: np.ndarray, receivers: np.ndarray) -> None:
        """Steps 1 and 8: a robot that finds a target broadcasts its position to all robots.

        ``found (m, T)``: the targets to announce to each of ``receivers (m,)``.
        """
        self.targets[receivers] |= found

    def frontier_empty(self) -> np.ndarray:
        """Stop rule (4) per robot: every vertex of its map that is not blocked has been
        stood on and sensed around (so no discovered vertex is unvisited, and no visited
        vertex has an unknown neighbourhood). The known vertices then form a set closed
        under travellable edges: the whole accessible component."""
        visited, discovered, blocked, sensed = (self.layers[:, k] for k in range(4))
        return ~np.any((discovered | visited) & ~sensed & ~blocked, axis=1)
