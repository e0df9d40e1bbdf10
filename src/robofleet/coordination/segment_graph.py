"""Segment graph (the label-flipping deadlock paper (2021), Definition 3), its active subgraph and cycle tests.

Vertices
    Each robot's path ``0..K_i`` is cut into maximal segments at the steps where it
    reaches or clears its collision segments (Definition 2). A vertex stands for the
    *moment its segment is entered*; a vertex is *done* once the robot's progress has
    reached its first step. The active subgraph of the paper (present + future vertices)
    is, on entry moments, the set of vertices not done: the present segment's *end* is the
    next vertex's entry.
Edges
    Path-sequence edges join consecutive segments of a robot. For an obstacle ``o``
    labelled ``a`` with waiter ``w``, obstacle-label edges say "``w`` may not enter step
    ``c`` before ``a`` has entered step ``q``".

Resolution (deviation from the literal Definition 3, documented in docs/results)
    ``"definition3"`` draws one edge per obstacle, from ``a``'s segment that begins when
    ``a`` clears ``o`` (``T_a + 1``) to ``w``'s segment that begins at ``o`` (``L_w``): the
    paper's edge, written on entry moments. Eq. 1 is finer: it lets ``w`` advance column
    by column as soon as ``a`` is above that column's highest cell, so a cycle in that
    graph need not be a deadlock. ``"exact"`` (default) cuts ``w``'s path at every column
    where the obstacle's running top row rises and draws one edge per such column, which
    encodes Eq. 1 exactly: with non-conflicting trajectories the active subgraph then has
    a cycle **iff** the execution deadlocks (Theorems 1 and 2; property-tested).

    The literal graph can even be cyclic for the plan's own labels: the plan lets ``w``
    enter ``o`` while ``a`` is still inside (above that column), which the single edge
    forbids, and two such obstacles of one pair of overlapping collision segments close a
    cycle although plain RMTRACK finishes the plan. The detector then keeps no order
    (:attr:`IncrementalCycleDetector.order` is ``None``) and answers each flip with the
    reference test on the active subgraph — a flip is kept only when the literal graph is
    acyclic after it — until a kept flip leaves the active subgraph acyclic and a fresh
    order is built. Since every exact cycle is a literal one, the literal check stays
    conservative: it refuses every flip that would deadlock, and some that would not.

Cycle tests
    :func:`has_cycle_full` rebuilds the active subgraph from the labels and the progress
    and runs a strongly-connected-components pass, ``O(V + E)`` — the reference.
    :class:`IncrementalCycleDetector` keeps a topological order of the whole graph and, when
    a flip adds edges ``u → v`` against that order, searches only the nodes whose order
    lies between ``v`` and ``u`` (Pearce & Kelly 2006). Flips only add edges between not
    yet entered vertices, so a cycle in the whole graph is a cycle of the active subgraph.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
import heapq

import numba
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..core.errors import InfeasibleError
from .coordination_space import CoordinationSpace
from .options import Resolution


@dataclass(frozen=True)
class SegmentLayout:
    """Vertices and all possible edges of the segment graph of a coordination space.

    Attributes
    ----------
    node_robot, node_start:
        ``(V,)`` robot and first step of each segment (sorted by robot, step).
    robot_first_node:
        ``(n + 1,)`` index of each robot's first vertex (CSR-style).
    path_src, path_dst:
        path-sequence edges.
    edge_side, edge_src, edge_dst:
        obstacle-label edges; an edge exists when the label of
        its side's obstacle is the side's other robot.
    """

    node_robot: np.ndarray
    node_start: np.ndarray
    robot_first_node: np.ndarray
    path_src: np.ndarray
    path_dst: np.ndarray
    edge_side: np.ndarray
    edge_src: np.ndarray
    edge_dst: np.ndarray
    side_obstacle: np.ndarray
    side_other: np.ndarray
    resolution: Resolution

    @property
    def n_nodes(self) -> int:
        return int(len(self.node_robot))

    def side_edges(self, side: int) -> tuple[np.ndarray, np.ndarray]:
        """Edges ``(src, dst)`` of one side (drawn while the side is active)."""
        lo, hi = np.searchsorted(self.edge_side, [side, side + 1])
        return self.edge_src[lo:hi], self.edge_dst[lo:hi]

    def active_edges(self, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """All edges ``(src, dst)`` of the whole graph for the given labels."""
        active = labels[self.side_obstacle] == self.side_other
        mask = active[self.edge_side]
        return np.concatenate([self.path_src, self.edge_src[mask]]), np.concatenate([self.path_dst, self.edge_dst[mask]])

    def done(self, progress: np.ndarray) -> np.ndarray:
        """Vertices already entered (not in the active subgraph)."""
        return progress[self.node_robot] >= self.node_start

    def node_of(self, robot: int, step: int) -> int:
        """The vertex whose segment contains ``step`` of ``robot``."""
        lo, hi = self.robot_first_node[robot], self.robot_first_node[robot + 1]
        return int(lo + np.searchsorted(self.node_start[lo:hi], step, side="right") - 1)


def build_segment_layout(space: CoordinationSpace, resolution: Resolution | str = Resolution.EXACT) -> SegmentLayout:
    """Cut every path at its collision-segment boundaries and list all possible edges.

    Complexity ``O(P log P)`` for ``P`` profile entries (all vectorized).
    """
    resolution = Resolution(resolution)
    side_c, side_q, side_id = _side_breakpoints(space, resolution)
    n = space.n_robots
    big = int(space.lengths.max(initial=0)) + 3
    waiter = space.side_waiter[side_id]
    other = space.side_other[side_id]
    keys = np.unique(np.concatenate([np.arange(n) * big, waiter * big + side_c, other * big + side_q]))
    node_robot, node_start = keys // big, keys % big
    first = np.searchsorted(node_robot, np.arange(n + 1))
    same = node_robot[1:] == node_robot[:-1]
    path_src = np.flatnonzero(same)
    order = np.argsort(side_id, kind="stable")
    return SegmentLayout(
        node_robot=node_robot, node_start=node_start, robot_first_node=first,
        path_src=path_src, path_dst=path_src + 1,
        edge_side=side_id[order],
        edge_src=np.searchsorted(keys, (other * big + side_q)[order]),
        edge_dst=np.searchsorted(keys, (waiter * big + side_c)[order]),
        side_obstacle=space.side_obstacle, side_other=space.side_other, resolution=resolution,
    )


def _side_breakpoints(space: CoordinationSpace, resolution: Resolution) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per side, the waiter steps ``c`` where Eq. 1's requirement rises and the other robot's
    step ``q`` it must have entered first (``q = max_{L ≤ c' ≤ c} top(c') + 1``)."""
    n_sides = len(space.side_lo)
    if resolution is Resolution.DEFINITION3:
        ids = np.arange(n_sides)
        return space.side_lo.copy(), space.side_other_hi + 1, ids
    sizes = space.side_hi - space.side_lo + 1
    side_of_entry = np.repeat(np.arange(n_sides), sizes)
    big = int(space.lengths.max(initial=0)) + 3
    running = np.maximum.accumulate(space.profile + side_of_entry * big) - side_of_entry * big
    step_in_side = np.arange(len(space.profile)) - space.side_offset[side_of_entry]
    rises = np.ones(len(running), dtype=bool)
    rises[1:] = (running[1:] > running[:-1]) | (side_of_entry[1:] != side_of_entry[:-1])
    ids = side_of_entry[rises]
    return space.side_lo[ids] + step_in_side[rises], running[rises] + 1, ids


def has_cycle_full(layout: SegmentLayout, labels: np.ndarray, progress: np.ndarray) -> bool:
    """Reference test: does the active subgraph (vertices not yet entered) contain a cycle?

    Rebuilds the graph from scratch and runs a strongly-connected-components pass; a
    cycle exists iff some component has more than one vertex (there are no self-loops).
    ``O(V + E)``.
    """
    return len(find_cycle_nodes(layout, labels, progress)) > 0


def find_cycle_nodes(layout: SegmentLayout, labels: np.ndarray, progress: np.ndarray) -> np.ndarray:
    """Vertices of the active subgraph that lie on a cycle (empty when acyclic)."""
    src, dst = layout.active_edges(labels)
    done = layout.done(progress)
    keep = ~done[src] & ~done[dst]
    v = layout.n_nodes
    graph = coo_matrix((np.ones(int(keep.sum()), dtype=np.int8), (src[keep], dst[keep])), shape=(v, v))
    _, comp = connected_components(graph, directed=True, connection="strong")
    sizes = np.bincount(comp, minlength=v)
    return np.flatnonzero(sizes[comp] > 1)


class IncrementalCycleDetector:
    """Segment graph with a maintained topological order (Pearce & Kelly 2006).

    ``try_flip`` replaces an obstacle's edges by those of the other label and keeps the
    flip only if no cycle appears; the search visits only the vertices whose topological
    index lies between the new edge's head and tail (the affected region).

    ``progress`` (optional, the robots' steps): the order is built on the active subgraph
    only (the vertices entered come first, in index order), for a graph whose entered
    part may hold cycles that no longer matter; every later ``try_flip`` must then pass a
    progress at least as far. With the exact resolution a cycle among the vertices the
    order covers is an error (:class:`~robofleet.core.errors.InfeasibleError`).
    """

    def __init__(self, layout: SegmentLayout, labels: np.ndarray, progress: np.ndarray | None = None):
        self.layout = layout
        self.labels = np.array(labels, copy=True)
        v = layout.n_nodes
        self.succ: list[dict[int, int]] = [dict() for _ in range(v)]
        self.pred: list[dict[int, int]] = [dict() for _ in range(v)]
        src, dst = layout.active_edges(self.labels)
        for (u, w), count in Counter(zip(src.tolist(), dst.tolist())).items():  # first-insertion order, as edge by edge
            self.succ[u][w] = count
            self.pred[w][u] = count
        self._node_robot = layout.node_robot.tolist()
        self._node_start = layout.node_start.tolist()
        self.visited_last = 0
        # topological index of every vertex (a list: fast scalar access); None while the
        # literal Definition 3 graph of the plan is cyclic (see the module docstring)
        self.order = self._topological_order(src, dst, progress)
        if self.order is None and layout.resolution is Resolution.EXACT:
            now = self._nothing_entered() if progress is None else np.asarray(progress)
            stuck = find_cycle_nodes(layout, self.labels, now)[:6].tolist()
            raise InfeasibleError(f"trajectories: expected plan labels without a cycle, received a cycle among segments {stuck}")

    def _nothing_entered(self) -> np.ndarray:
        """Progress ``-1`` for every robot: the whole graph is the active subgraph."""
        return np.full(len(self.layout.robot_first_node) - 1, -1, dtype=np.intp)

    def _topological_order(self, src: np.ndarray, dst: np.ndarray, progress: np.ndarray | None = None) -> list[int] | None:
        """A topological order close to plan time of the graph with edges ``src → dst``
        (its active subgraph for ``progress``), or ``None`` when it has a cycle
        (:func:`earliest_first_order`)."""
        v = self.layout.n_nodes
        entered = np.zeros(v, dtype=bool) if progress is None else self.layout.done(np.asarray(progress))
        order = earliest_first_order(np.ascontiguousarray(src, dtype=np.intp), np.ascontiguousarray(dst, dtype=np.intp),
                                     np.ascontiguousarray(self.layout.node_start, dtype=np.intp), entered)
        return order.tolist() if v == 0 or order[0] >= 0 else None

    def _edges(self) -> tuple[np.ndarray, np.ndarray]:
        """The graph's edges ``(src, dst)`` now, one entry per parallel edge."""
        pairs = [(u, w) for u, table in enumerate(self.succ) for w, count in table.items() for _ in range(count)]
        edges = np.array(pairs, dtype=np.intp).reshape(-1, 2)
        return edges[:, 0], edges[:, 1]

    def _insert(self, u: int, w: int) -> None:
        self.succ[u][w] = self.succ[u].get(w, 0) + 1
        self.pred[w][u] = self.pred[w].get(u, 0) + 1

    def _remove(self, u: int, w: int) -> None:
        for table, a, b in ((self.succ, u, w), (self.pred, w, u)):
            count = table[a][b] - 1
            if count:
                table[a][b] = count
            else:
                del table[a][b]

    def add_edge(self, u: int, w: int, progress: list[int] | None = None) -> bool:
        """Insert ``u → w`` unless it closes a cycle; return whether it was inserted.

        With ``progress`` the searches skip vertices already entered and stay in the active
        subgraph: no edge leads from a vertex not entered to an entered one, so a cycle
        through ``u → w`` lies in it, and the maintained order only has to stay valid there.
        """
        order = self.order
        if w in self.succ[u] or order[u] < order[w]:
            self._insert(u, w)
            return True
        lo, hi = order[w], order[u]
        if progress is None:
            forward = self._search(w, self.succ, lambda x: order[x] <= hi, target=u)
        else:
            robot, start = self._node_robot, self._node_start
            forward = self._search(w, self.succ, lambda x: order[x] <= hi and progress[robot[x]] < start[x], target=u)
        if forward is None:
            return False
        if progress is None:
            backward = self._search(u, self.pred, lambda x: order[x] >= lo, target=None)
        else:
            backward = self._search(u, self.pred, lambda x: order[x] >= lo and progress[robot[x]] < start[x], target=None)
        self._reorder(forward, backward)
        self._insert(u, w)
        return True

    def _search(self, start: int, table, inside, target):
        """Depth-first search from ``start`` within the affected region; ``None`` if ``target`` is reached."""
        seen, stack = {start}, [start]
        while stack:
            x = stack.pop()
            for y in table[x]:
                if y == target:
                    self.visited_last += len(seen)
                    return None
                if y not in seen and inside(y):
                    seen.add(y)
                    stack.append(y)
        self.visited_last += len(seen)
        return seen

    def _reorder(self, forward: set, backward: set) -> None:
        order = self.order
        back = sorted(backward, key=order.__getitem__)
        fwd = sorted(forward, key=order.__getitem__)
        slots = sorted(order[x] for x in back + fwd)
        for x, slot in zip(back + fwd, slots):
            order[x] = slot

    def try_flip(self, obstacle: int, new_label: int, progress: np.ndarray | None = None) -> bool:
        """Give ``obstacle`` the label ``new_label`` unless that closes a cycle.

        ``progress`` (the robots' current steps) restricts the search to the active
        subgraph. Returns ``True`` (flip kept) or ``False`` (graph unchanged, the robot
        keeps waiting).
        """
        if self.order is None:
            return self._flip_without_order(obstacle, new_label, progress)
        steps = None if progress is None else [int(v) for v in progress]
        old_side, new_side = self._sides(obstacle, new_label)
        old_src, old_dst = self.layout.side_edges(old_side)
        new_src, new_dst = self.layout.side_edges(new_side)
        self.visited_last = 0
        for u, w in zip(old_src.tolist(), old_dst.tolist()):
            self._remove(u, w)
        added = []
        for u, w in zip(new_src.tolist(), new_dst.tolist()):
            if not self.add_edge(u, w, steps):
                for a, b in added:
                    self._remove(a, b)
                for a, b in zip(old_src.tolist(), old_dst.tolist()):
                    self.add_edge(a, b, steps)
                return False
            added.append((u, w))
        self.labels[obstacle] = new_label
        return True

    def _flip_without_order(self, obstacle: int, new_label: int, progress: np.ndarray | None) -> bool:
        """:meth:`try_flip` while the graph is cyclic (literal Definition 3 on the plan's
        labels): the reference test on the tentative labels, ``O(V + E)``; a kept flip
        that leaves the active subgraph acyclic brings back the maintained order."""
        now = self._nothing_entered() if progress is None else np.asarray(progress)
        tentative = self.labels.copy()
        tentative[obstacle] = new_label
        self.visited_last = self.layout.n_nodes
        if has_cycle_full(self.layout, tentative, now):
            return False
        old_side, new_side = self._sides(obstacle, new_label)
        for u, w in zip(*(e.tolist() for e in self.layout.side_edges(old_side))):
            self._remove(u, w)
        for u, w in zip(*(e.tolist() for e in self.layout.side_edges(new_side))):
            self._insert(u, w)
        self.labels[obstacle] = new_label
        self.order = self._topological_order(*self._edges(), None if progress is None else now)
        return True

    def _sides(self, obstacle: int, new_label: int) -> tuple[int, int]:
        """(side active now, side active after the flip); the active side's waiter is not the label."""
        first = 2 * obstacle
        old_side = first if self.layout.side_other[first] == self.labels[obstacle] else first + 1
        new_side = first if self.layout.side_other[first] == new_label else first + 1
        return old_side, new_side


@numba.njit(cache=True)
def earliest_first_order(src, dst, start, entered):
    """Kahn's algorithm that always takes the ready vertex whose segment starts earliest
    (ties: lower index), over the vertices not ``entered``; entered vertices come first, in
    index order (no search enters them). Parallel edges count once each.

    Taking the earliest segment keeps the order close to plan time, so new flip edges
    mostly point between nearby moments and the Pearce–Kelly search region stays small.
    Returns the index of every vertex in the order ``(V,)``, or ``[-1, …]`` when the
    vertices not entered hold a cycle. ``O((V + E) log V)``.
    """
    v = len(start)
    indegree = np.zeros(v, dtype=np.intp)
    first = np.zeros(v + 1, dtype=np.intp)
    for e in range(len(src)):
        first[src[e] + 1] += 1
        if not entered[src[e]]:
            indegree[dst[e]] += 1
    first = np.cumsum(first)
    succ = np.empty(len(src), dtype=np.intp)
    fill = first[:-1].copy()
    for e in range(len(src)):
        succ[fill[src[e]]] = dst[e]
        fill[src[e]] += 1
    order = np.full(v, -1, dtype=np.intp)
    position = 0
    for x in range(v):
        if entered[x]:
            order[x] = position
            position += 1
    ready = [(start[x], x) for x in range(v) if not entered[x] and indegree[x] == 0]
    heapq.heapify(ready)
    while len(ready) > 0:
        _, x = heapq.heappop(ready)
        order[x] = position
        position += 1
        for e in range(first[x], first[x + 1]):
            y = succ[e]
            indegree[y] -= 1
            if indegree[y] == 0 and not entered[y]:
                heapq.heappush(ready, (start[y], y))
    if position < v:
        order[:] = -1
    return order
