"""Who is near whom at a step: robots within ``r_c`` / ``r_so``, found by spatial hashing.

Paper 002, Section 2: a robot's communication neighbours ``N_c,i(k)`` are the robots within
``r_c``; its sonars sense the bodies within ``r_so``. Both ranges are a couple of edges, so
a robot has a bounded number of neighbours whatever the team size. The robots are bucketed
into square cells of side ``max(r_c, r_so)`` (key: run, cell column, cell row; one sort),
and each robot looks only into the 3 × 3 cells around its own: O(N log N) for the sort
and O(N · c) for N robots with c robots per neighbourhood — no all-pairs distances.

The result is a compressed sparse row table (:class:`Neighbours`): for robot ``i`` the
entries ``start[i] … start[i + 1] − 1`` list the robots ``j ≠ i`` of its run within the
larger range, in increasing id, with ``link`` (``j ∈ N_c,i``, both alive), ``sensed``
(``j`` within ``r_so`` of alive ``i``; failed robots included) and ``near`` (within ``r_c``
or ``r_so``, alive or not: what failure detection reads). The order is the order of the
dense ``(run, i, j)`` relation, so everything read from it comes out in the same order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass(frozen=True, eq=False)
class Neighbours:
    """Sparse neighbour relation of ``N`` robots in runs of ``n`` (see the module docstring)."""

    n: int
    start: np.ndarray
    peer: np.ndarray
    link: np.ndarray
    sensed: np.ndarray
    owner: np.ndarray
    """``(L,)`` the robot each entry belongs to."""

    @property
    def aware(self) -> np.ndarray:
        """``(L,)`` entries the robot knows the position of: linked or sensed."""
        return self.link | self.sensed

    def linked(self) -> np.ndarray:
        """``(N,)`` robots with at least one communication neighbour."""
        out = np.zeros(len(self.start) - 1, dtype=bool)
        out[self.owner[self.link]] = True
        return out

    def entries_of(self, robots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(rows, entries)``: for each entry of each of ``robots``, its row in ``robots`` and
        its entry index (rows ascending, entries in the table's order)."""
        first, count = self.start[robots], self.start[robots + 1] - self.start[robots]
        rows = np.repeat(np.arange(len(robots)), count)
        offset = np.arange(len(rows)) - np.repeat(np.cumsum(count) - count, count)
        return rows, first[rows] + offset


def no_neighbours(n_total: int, n: int) -> Neighbours:
    """The empty relation (single robots, or no robot near another)."""
    empty = np.zeros(0, dtype=bool)
    none = np.zeros(0, dtype=np.int64)
    return Neighbours(n, np.zeros(n_total + 1, dtype=np.int64), none, empty, empty, none)


def find_neighbours(points: np.ndarray, n: int, alive: np.ndarray, rc2: float, rso2: float) -> tuple[Neighbours, np.ndarray]:
    """Neighbours of robots at ``points (N, 2)`` in runs of ``n`` (squared ranges ``rc2``, ``rso2``).

    Returns the relation and ``near (L,)``: entries within ``r_c`` or ``r_so`` (every entry).
    Robots on one vertex (possible for RU and LFP after a collision) are neighbours.
    """
    r2 = max(rc2, rso2)
    h = max(float(np.sqrt(r2)) * (1 + 1e-9), 1e-12)  # cells no narrower than the range, rounding included
    pts = np.ascontiguousarray(points, dtype=np.float64)
    start, peer, d2 = _pairs_within(pts, np.int64(n), h, r2)
    in_rc, in_rso = d2 <= rc2, d2 <= rso2
    owner = np.repeat(np.arange(len(pts)), np.diff(start))
    link = in_rc & alive[owner] & alive[peer]
    sensed = in_rso & alive[owner]
    return Neighbours(n, start, peer, link, sensed, owner), in_rc | in_rso


def from_dense(links: np.ndarray, sensed: np.ndarray) -> Neighbours:
    """The relation given as dense ``(R, n, n)`` boolean matrices (tests and hand-built contexts)."""
    runs, n = links.shape[0], links.shape[-1]
    either = (links | sensed).reshape(runs * n, n)
    owner, local = np.nonzero(either)
    peer = (owner // n) * n + local
    start = np.concatenate([[0], np.cumsum(either.sum(axis=1))]).astype(np.int64)
    flat_links, flat_sensed = links.reshape(runs * n, n), sensed.reshape(runs * n, n)
    return Neighbours(n, start, peer.astype(np.int64), flat_links[owner, local], flat_sensed[owner, local], owner)


@numba.njit(cache=True)
def _pairs_within(pts, n, h, r2):
    """CSR ``(start, peer, d2)`` of the pairs of one run within squared distance ``r2``.

    Cell key = (run · columns + cx) · rows + cy over the points' bounding box; the points are
    sorted by key once, and each point scans its 3 × 3 cells — three runs of consecutive
    keys — by binary search in that order; its entries are then put in increasing id.
    """
    N = len(pts)
    start = np.zeros(N + 1, dtype=np.int64)
    peer, d2s = np.empty(max(8 * N, 16), dtype=np.int64), np.empty(max(8 * N, 16))
    if N == 0:
        return start, peer[:0], d2s[:0]
    x0, y0 = pts[:, 0].min(), pts[:, 1].min()
    cx = np.floor((pts[:, 0] - x0) / h).astype(np.int64)
    cy = np.floor((pts[:, 1] - y0) / h).astype(np.int64)
    cols, rows = cx.max() + 3, cy.max() + 3
    key = ((np.arange(N) // n) * cols + cx + 1) * rows + cy + 1
    order = np.argsort(key, kind="mergesort")
    sorted_key = key[order]
    count = np.int64(0)  # typed from the start: _sort_segment is compiled for int64 only
    for i in range(N):
        for dx in range(-1, 2):
            k = key[i] + dx * rows
            for t in range(np.searchsorted(sorted_key, k - 1), np.searchsorted(sorted_key, k + 1, side="right")):
                j = order[t]
                ex, ey = pts[i, 0] - pts[j, 0], pts[i, 1] - pts[j, 1]
                d2 = ex * ex + ey * ey
                if j != i and d2 <= r2:
                    if count == len(peer):
                        peer, d2s = np.concatenate((peer, peer)), np.concatenate((d2s, d2s))
                    peer[count], d2s[count] = j, d2
                    count += 1
        start[i + 1] = count
        _sort_segment(peer, d2s, start[i], count)
    return start, peer[:count].copy(), d2s[:count].copy()


@numba.njit(cache=True)
def _sort_segment(peer, d2s, lo, hi):
    """Insertion sort of ``peer[lo:hi]`` (a robot's few entries), carrying ``d2s`` along."""
    for a in range(lo + 1, hi):
        p, d = peer[a], d2s[a]
        b = a - 1
        while b >= lo and peer[b] > p:
            peer[b + 1], d2s[b + 1] = peer[b], d2s[b]
            b -= 1
        peer[b + 1], d2s[b + 1] = p, d


# -- the choice order of step 4 (used by the policies) ---------------------------------------
@numba.njit(cache=True)
def longest_waiting_chain(rank, start, peer, link, active):
    """Round of every robot in step 4: 0 without a higher-ranked active linked peer, else one
    more than the largest round among them; ``-1`` for inactive robots. Robots are taken in
    decreasing rank, so every robot's higher-ranked peers are done before it (a DAG)."""
    level = np.full(len(rank), -1, dtype=np.int64)
    for i in np.argsort(-rank, kind="mergesort"):
        if not active[i]:
            continue
        lv = 0
        for e in range(start[i], start[i + 1]):
            j = peer[e]
            if link[e] and active[j] and rank[j] > rank[i]:
                lv = max(lv, level[j] + 1)
        level[i] = lv
    return level


# -- collisions of a move (observer side) ----------------------------------------------------
def collision_pairs(pos: np.ndarray, choice: np.ndarray, n: int, n_vertices: int) -> np.ndarray:
    """``(K, 3)`` rows ``(run, i, j)``, ``i < j`` local ids, of robots that collide in a move:
    same destination, or swapping along one edge; sorted. O(N log N) by sorting on vertices."""
    run = np.arange(len(pos)) // n
    return _collision_pairs(run * n_vertices + pos, run * n_vertices + choice, np.int64(n))


@numba.njit(cache=True)
def _collision_pairs(here, dest, n):
    """Pairs sharing a destination key, or with ``dest[i] = here[j]``, ``dest[j] = here[i]``, ``i`` moving."""
    N = len(here)
    by_dest, by_here = np.argsort(dest, kind="mergesort"), np.argsort(here, kind="mergesort")
    dest_sorted, here_sorted = dest[by_dest], here[by_here]
    keys = []
    for t in range(N):
        i = by_dest[t]
        u = t + 1
        while u < N and dest_sorted[u] == dest[i]:
            j = by_dest[u]
            keys.append(min(i, j) * N + max(i, j))
            u += 1
        if dest[i] != here[i]:
            lo, hi = np.searchsorted(here_sorted, dest[i]), np.searchsorted(here_sorted, dest[i], side="right")
            for s in range(lo, hi):
                j = by_here[s]
                if dest[j] == here[i] and j != i:
                    keys.append(min(i, j) * N + max(i, j))
    unique = np.unique(np.array(keys, dtype=np.int64)) if len(keys) else np.zeros(0, dtype=np.int64)
    out = np.empty((len(unique), 3), dtype=np.int64)
    for r in range(len(unique)):
        i, j = unique[r] // N, unique[r] % N
        out[r, 0], out[r, 1], out[r, 2] = i // n, i % n, j % n
    return out
