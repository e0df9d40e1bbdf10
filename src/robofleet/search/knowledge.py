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

Every row is split into blocks of :data:`BLOCK_WORDS` words; the maps note which blocks of
a robot ever held a bit (``touched``) and which changed since the last exchange
(``dirty``) or the last stop check (``unchecked``). A robot linked to the same sender at
the previous exchange already holds the sender's map as it was then (maps only grow), so
the sender's message needs only the blocks changed since; a new link carries every touched
block. The exchange, and stop rule (4), so cost O(links · changed blocks) per step rather
than O(links · V): the result is the one-hop OR of whole maps.
"""

from __future__ import annotations

import numba
import numpy as np

from .map_words import BLOCK_WORDS, LAYERS, WORD

ONE = np.uint64(1)


class RobotMaps:
    """Per-robot knowledge of ``n_robots`` robots on a grid of ``n_vertices`` vertices."""

    def __init__(self, n_robots: int, n_vertices: int, n_targets: int):
        words = -(-n_vertices // WORD)
        blocks = -(-words // BLOCK_WORDS)
        self.n_vertices = n_vertices
        # layers: 0 visited, 1 discovered, 2 blocked, 3 sensed
        self.layers = np.zeros((n_robots, LAYERS, blocks * BLOCK_WORDS), dtype=np.uint64)
        self.targets = np.zeros((n_robots, n_targets), dtype=bool)
        self.touched = np.zeros((n_robots, blocks), dtype=bool)
        self.dirty = np.zeros((n_robots, blocks), dtype=bool)
        self.unchecked = np.zeros((n_robots, blocks), dtype=bool)
        self.open = np.zeros((n_robots, blocks), dtype=bool)
        self.last_links = np.zeros(0, dtype=np.int64)

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
        robots = np.asarray(robots, dtype=np.int64).ravel()
        vertices = np.asarray(vertices, dtype=np.int64).ravel()
        if len(vertices):
            _set_bits(self.layers, self.touched, self.dirty, self.unchecked, layer, robots, vertices)

    def as_bool(self, layer: int) -> np.ndarray:
        """``(n_robots, V)`` boolean view of one layer (for checks and plots, not hot paths)."""
        bits = np.unpackbits(self.layers[:, layer, :].view(np.uint8), axis=1, bitorder="little")
        return bits[:, : self.n_vertices].astype(bool)

    # -- messages -----------------------------------------------------------------------
    def exchange(self, receivers: np.ndarray, senders: np.ndarray) -> None:
        """Step 3: every robot ORs in the maps of its communication neighbours.

        ``receivers``, ``senders`` ``(L,)``: robot ``receivers[e]`` receives the message of
        ``senders[e]`` this step (``senders[e] ∈ N_c,receivers[e](k)``, both alive), sorted
        by receiver then sender. One hop per step, as in the paper's temporary ad-hoc
        networks: every message is the sender's map before this exchange.
        """
        n = len(self.layers)
        keys = receivers.astype(np.int64) * n + senders
        fresh = _not_in_sorted(keys, self.last_links)
        self.last_links = keys
        if len(keys):
            _exchange(self.layers, self.touched, self.dirty, self.unchecked, receivers.astype(np.int64),
                      senders.astype(np.int64), fresh, self.targets)
        else:
            self.dirty[:] = False

    def broadcast_targets(self, found: np.ndarray, receivers: np.ndarray) -> None:
        """Steps 1 and 8: a robot that finds a target broadcasts its position to all robots.

        ``found (m, T)``: the targets to announce to each of ``receivers (m,)``.
        """
        self.targets[receivers] |= found

    def frontier_empty(self) -> np.ndarray:
        """Stop rule (4) per robot: every vertex of its map that is not blocked has been
        stood on and sensed around (so no discovered vertex is unvisited, and no visited
        vertex has an unknown neighbourhood). The known vertices then form a set closed
        under travellable edges: the whole accessible component. Only blocks changed since
        the last check are re-read."""
        return _frontier_empty(self.layers, self.unchecked, self.open)


@numba.njit(cache=True, inline="always")
def set_bit(layers, touched, dirty, unchecked, layer, robot, vertex):
    """OR the bit of ``vertex`` into row ``robot`` of ``layer``; mark its block changed."""
    layers[robot, layer, vertex >> 6] |= np.uint64(1) << np.uint64(vertex & 63)
    b = (vertex >> 6) // BLOCK_WORDS
    touched[robot, b] = dirty[robot, b] = unchecked[robot, b] = True


@numba.njit(cache=True)
def _set_bits(layers, touched, dirty, unchecked, layer, robots, vertices):
    """:func:`set_bit` for the pairs ``(robots[j], vertices[j])``."""
    for t in range(len(robots)):
        set_bit(layers, touched, dirty, unchecked, layer, robots[t], vertices[t])


@numba.njit(cache=True)
def _not_in_sorted(keys, sorted_keys):
    """Per entry of ``keys``: absent from the ascending array ``sorted_keys`` (binary search)."""
    out = np.ones(len(keys), dtype=np.bool_)
    for e in range(len(keys)):
        t = np.searchsorted(sorted_keys, keys[e])
        out[e] = t == len(sorted_keys) or sorted_keys[t] != keys[e]
    return out


@numba.njit(cache=True)
def _exchange(layers, touched, dirty, unchecked, receivers, senders, fresh, targets):
    """One-hop OR of the senders' maps and targets as they were before the exchange.

    A message carries every touched block of a fresh link, else the blocks the sender
    changed since the last exchange; the messages are copied out first (the sender's old
    map), then ORed in, marking a receiver's block changed only when a bit is new.
    """
    n_blocks = touched.shape[1]
    count = 0
    for e in range(len(senders)):
        flags = touched[senders[e]] if fresh[e] else dirty[senders[e]]
        for b in range(n_blocks):
            count += flags[b]
    message = np.empty((count, LAYERS, BLOCK_WORDS), dtype=np.uint64)
    dest = np.empty(count, dtype=np.int64)
    block = np.empty(count, dtype=np.int64)
    c = 0
    for e in range(len(senders)):
        j = senders[e]
        flags = touched[j] if fresh[e] else dirty[j]
        for b in range(n_blocks):
            if flags[b]:
                for layer in range(LAYERS):  # element by element: no broadcasting machinery to compile
                    for w in range(BLOCK_WORDS):
                        message[c, layer, w] = layers[j, layer, b * BLOCK_WORDS + w]
                dest[c], block[c] = receivers[e], b
                c += 1
    heard = targets[senders].copy()
    dirty[:] = False
    for c in range(count):
        i, b = dest[c], block[c]
        changed = False
        for layer in range(LAYERS):
            for w in range(BLOCK_WORDS):
                old = layers[i, layer, b * BLOCK_WORDS + w]
                new = old | message[c, layer, w]
                if new != old:
                    layers[i, layer, b * BLOCK_WORDS + w] = new
                    changed = True
        if changed:
            touched[i, b] = dirty[i, b] = unchecked[i, b] = True
    for e in range(len(receivers)):
        for t in range(targets.shape[1]):
            targets[receivers[e], t] |= heard[e, t]


@numba.njit(cache=True)
def _frontier_empty(layers, unchecked, open_):
    """Per robot: no block holds a discovered-or-visited vertex neither sensed nor blocked
    (``open_`` caches each block's answer; blocks flagged ``unchecked`` are re-read)."""
    n, n_blocks = unchecked.shape
    out = np.ones(n, dtype=np.bool_)
    for i in range(n):
        for b in range(n_blocks):
            if unchecked[i, b]:
                unchecked[i, b] = False
                is_open = False
                for w in range(b * BLOCK_WORDS, (b + 1) * BLOCK_WORDS):
                    if (layers[i, 1, w] | layers[i, 0, w]) & ~layers[i, 3, w] & ~layers[i, 2, w]:
                        is_open = True
                open_[i, b] = is_open
            if open_[i, b]:
                out[i] = False
    return out
