"""BTPG: passing orders that may switch safely, then first come, first served.

A reimplementation, from the published description, of the *bidirectional temporal plan
graph* (Su, Veerapaneni & Li, "Bidirectional Temporal Plan Graph: Enabling Switchable
Passing Orders for More Efficient Multi-Agent Path Finding Plan Execution", AAAI 2024),
carried over from the temporal plan graph of a grid MAPF plan to the segment graph of the
label-flipping deadlock paper (2021, Definition 3; here its exact resolution,
:mod:`.segment_graph`). No code of the authors was used.

Offline (:func:`classify_switchable`)
    Every coordination-space obstacle starts *fixed* at its plan label (the plan's passing
    order). Obstacles are visited in plan-time order of their first entry; obstacle ``o``
    becomes *switchable* when making it so keeps this invariant:

        (I) for every assignment of labels to the switchable obstacles (the others at
        their plan labels) the whole segment graph is acyclic.

    The test (the paper's "naïve" construction, BTPG-naïve): in the *relaxed* graph ``H``
    that holds the path-sequence edges, the plan-label edges of the fixed obstacles, the
    edges of *both* labels of every switchable obstacle and, for ``o``, only the edges of
    its reversed label, no reversed-label edge of ``o`` lies on a cycle (its tail is not
    reachable from its head).

    *Proof of (I).* It holds for no switchable obstacle: the plan labels' exact graph is
    acyclic on a valid plan. Let it hold for ``S`` and let ``o`` pass the test. An
    assignment of ``S ∪ {o}`` that gives ``o`` its plan label is an assignment of ``S``:
    acyclic. One that reverses ``o`` has a graph ``G ⊆ H``; a cycle of ``G`` that used no
    reversed edge of ``o`` would lie in the graph of the same assignment with ``o`` at its
    plan label (acyclic), so it uses a reversed edge ``u → v`` of ``o`` and ``u`` is
    reachable from ``v`` in ``G ⊆ H``, which the test excludes. ∎

    ``H`` also holds cycles that take both labels of one switchable obstacle, which no
    assignment has, so the test is conservative: it may keep fixed an obstacle that could
    switch (the paper's BTPG-optimized removes some of that conservatism by grouping and
    by recognising such cycles; not reimplemented here). Obstacles that a robot starts or
    ends in stay fixed: a label given to the robot parked at its goal would block the other
    forever, and one taken from a robot that starts inside cannot be enforced (see
    :func:`~.label_flipping.flip_eligible`).

    Complexity: one search of ``H`` per candidate, ``O(m (V + E))`` in the worst case for
    ``m`` obstacles, ``V`` segments and ``E`` edges, compiled; each search stops at the
    first cycle found and enters only vertices that can still lead back to the tail (see
    :func:`_classify`). Like the paper's constructions it is *anytime*: candidates are
    tested until ``budget`` vertices have been visited in all (a count, so that the result
    does not depend on the machine), and the obstacles not reached by then stay fixed —
    (I) holds after every candidate.

Online (:func:`first_come`)
    A robot stopped by a switchable obstacle whose label robot has not yet reached it takes
    the obstacle (the label flips to it) and the obstacle is settled for the rest of the
    run: whoever comes first passes first. Fixed obstacles keep the plan order (RMTRACK).
    The flip is made under the same condition as every flip of the family (the other robot
    has not reached the obstacle), so Eq. 1's invariant holds for the new label: no
    collision. With (I) the active segment graph is acyclic at every step, whatever the
    delays, so by Theorems 1–2 no deadlock happens when the plan is non-conflicting
    (Definition 4). Deviation: the AAAI paper settles a bidirectional pair at the moment a
    robot is *ready to enter* the shared location; here that is the moment Eq. 1 stops the
    robot at the obstacle (the first column whose highest cell the other robot has not
    passed), which is the finest event RMTRACK's discrete steps give.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numba
import numpy as np

from .coordination_space import CoordinationSpace
from .label_flipping import FlipContext
from .options import DEFAULT_VISIT_BUDGET
from .segment_graph import SegmentLayout


@dataclass(frozen=True)
class Classification:
    """Outcome of :func:`classify_switchable`.

    Attributes
    ----------
    switchable:
        ``(m,)`` bool: the obstacle's passing order may switch at run time.
    candidates:
        obstacles that neither robot starts or ends in.
    tested:
        candidates tested within the budget (the first ``tested`` in plan-time order).
    visited:
        vertices the searches visited.
    seconds:
        wall time of the classification.
    """

    switchable: np.ndarray
    candidates: int
    tested: int
    visited: int
    seconds: float

    @property
    def n_switchable(self) -> int:
        return int(self.switchable.sum())


def statically_switchable(space: CoordinationSpace) -> np.ndarray:
    """``(m,)`` bool: neither robot of the obstacle starts in it (``L > 0`` on both sides)
    nor ends in it (``R ≠ K`` on both sides) — the obstacles whose label either robot may hold."""
    if space.n_obstacles == 0:
        return np.zeros(0, dtype=bool)
    side_ok = (space.side_lo > 0) & (space.side_hi != space.lengths[space.side_waiter])
    return side_ok[0::2] & side_ok[1::2]


def plan_sides(space: CoordinationSpace, labels: np.ndarray) -> np.ndarray:
    """``(m,)`` index of the side each obstacle's label makes active (its other robot is the label)."""
    first = 2 * np.arange(space.n_obstacles)
    return np.where(space.side_other[first] == labels, first, first + 1)


def classify_switchable(space: CoordinationSpace, layout: SegmentLayout, budget: int = DEFAULT_VISIT_BUDGET) -> Classification:
    """Mark each obstacle fixed or switchable so that invariant (I) of the module holds.

    Parameters
    ----------
    space:
        the coordination space (plan labels in ``initial_labels``).
    layout:
        its segment layout with the exact resolution.
    budget:
        vertices the searches may visit in all; candidates after the one that exhausts it stay fixed.
    """
    t0 = time.perf_counter()
    m = space.n_obstacles
    eligible = statically_switchable(space)
    if m == 0 or not eligible.any():
        return Classification(np.zeros(m, dtype=bool), int(eligible.sum()), 0, 0, time.perf_counter() - t0)
    first_entry = np.minimum(space.side_lo[0::2], space.side_lo[1::2])
    candidates = np.flatnonzero(eligible)
    candidates = candidates[np.lexsort((candidates, first_entry[candidates]))]
    out_ptr, out_dst, out_side = label_edge_csr(layout, by="src")
    in_ptr, in_src, in_side = label_edge_csr(layout, by="dst")
    side_ptr = np.searchsorted(layout.edge_side, np.arange(2 * m + 1)).astype(np.intp)
    switchable, tested, visited = _classify(
        candidates.astype(np.intp), plan_sides(space, space.initial_labels).astype(np.intp), layout.node_robot.astype(np.intp),
        layout.node_start.astype(np.intp), out_ptr, out_dst, out_side, in_ptr, in_src, in_side, side_ptr,
        layout.edge_src.astype(np.intp), layout.edge_dst.astype(np.intp), m, int(budget),
    )
    return Classification(switchable, len(candidates), int(tested), int(visited), time.perf_counter() - t0)


def label_edge_csr(layout: SegmentLayout, by: str = "src") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All obstacle-label edges of the layout grouped by ``src`` (or ``dst``): ``(ptr (V + 1,),
    other end (E,), side (E,))``. Path-sequence edges are implicit (vertex ``v`` → ``v + 1``
    of the same robot)."""
    key = layout.edge_src if by == "src" else layout.edge_dst
    other = layout.edge_dst if by == "src" else layout.edge_src
    order = np.argsort(key, kind="stable")
    ptr = np.searchsorted(key[order], np.arange(layout.n_nodes + 1)).astype(np.intp)
    return ptr, other[order].astype(np.intp), layout.edge_side[order].astype(np.intp)


@numba.njit(cache=True)
def _classify(candidates, plan_side, node_robot, node_start, out_ptr, out_dst, out_side, in_ptr, in_src, in_side, side_ptr,
              edge_src, edge_dst, m, budget):
    """The greedy construction of :func:`classify_switchable`, compiled.

    Searches are pruned with ``low[y]``, the lowest plan step of a vertex reachable from
    ``y`` in the relaxed graph (``node_start`` while no obstacle is switchable: every edge
    of the plan's graph goes forward in plan time). A vertex with ``low[y] > q`` cannot
    reach the tail at plan step ``q``, so it is not entered. ``low`` is lowered along the
    reversed edges of each obstacle made switchable (backward label-correcting pass).

    The candidate's own reversed edges are left out of its searches: the heads lie on one
    robot's path and the tails on the other's, both in increasing step order, so a path
    through another reversed edge ``j`` of the candidate either reaches tail ``j ≤ k``
    (and tail ``k`` after it along the path) or jumps to head ``j > k``, already reachable
    from head ``k`` along the path.
    """
    v = len(node_robot)
    enabled = np.zeros(2 * m, dtype=np.uint8)
    for o in range(m):
        enabled[plan_side[o]] = 1
    low = node_start.copy()
    switchable = np.zeros(m, dtype=np.bool_)
    stamp = np.zeros(v, dtype=np.int64)
    stack = np.empty(v, dtype=np.intp)
    visited = 0
    tested = 0
    for index in range(len(candidates)):
        if visited >= budget:
            break
        tested += 1
        o = candidates[index]
        keep, rev = plan_side[o], plan_side[o] ^ 1
        enabled[keep] = 0
        mark = index + 1
        cycle = False
        # the reversed side's edges, latest head first: the heads lie on one robot's path in
        # step order, so each search only extends the set reached from the later heads
        for e in range(side_ptr[rev + 1] - 1, side_ptr[rev] - 1, -1):
            head, tail = edge_dst[e], edge_src[e]
            if stamp[head] != mark and low[head] <= node_start[tail]:
                visited += _reach(head, mark, node_start[tail], low, stamp, stack, node_robot, out_ptr, out_dst, out_side, enabled)
            if stamp[tail] == mark:
                cycle = True
                break
        enabled[keep] = 1
        if not cycle:
            enabled[rev] = 1
            switchable[o] = True
            _lower(rev, side_ptr, edge_src, edge_dst, low, stack, node_robot, in_ptr, in_src, in_side, enabled)
    return switchable, tested, visited


@numba.njit(cache=True)
def _reach(start, mark, limit, low, stamp, stack, node_robot, out_ptr, out_dst, out_side, enabled):
    """Mark (``stamp = mark``) the vertices reachable from ``start`` over the path-sequence
    edges and the enabled sides' label edges, entering only vertices with ``low ≤ limit``
    (the others cannot lead back to plan step ``limit``); marked vertices are not entered
    again. Returns the number of vertices marked."""
    v = len(node_robot)
    count = 1
    top = 0
    stamp[start] = mark
    stack[top] = start
    top += 1
    while top > 0:
        top -= 1
        x = stack[top]
        nxt = x + 1
        if nxt < v and node_robot[nxt] == node_robot[x] and stamp[nxt] != mark and low[nxt] <= limit:
            stamp[nxt] = mark
            stack[top] = nxt
            top += 1
            count += 1
        for e in range(out_ptr[x], out_ptr[x + 1]):
            y = out_dst[e]
            if enabled[out_side[e]] and stamp[y] != mark and low[y] <= limit:
                stamp[y] = mark
                stack[top] = y
                top += 1
                count += 1
    return count


@numba.njit(cache=True)
def _lower(side, side_ptr, edge_src, edge_dst, low, stack, node_robot, in_ptr, in_src, in_side, enabled):
    """After the edges of ``side`` joined the relaxed graph: ``low[u] = min(low[u], low[v])``
    for each new edge ``u → v``, carried back to every predecessor (path-sequence and enabled
    label edges) whose value drops. A vertex waits on the stack at most once at a time."""
    waiting = np.zeros(len(low), dtype=np.bool_)
    top = 0
    for e in range(side_ptr[side], side_ptr[side + 1]):
        u, w = edge_src[e], edge_dst[e]
        if low[w] < low[u]:
            low[u] = low[w]
            if not waiting[u]:
                waiting[u] = True
                stack[top] = u
                top += 1
    while top > 0:
        top -= 1
        y = stack[top]
        waiting[y] = False
        prev = y - 1
        if prev >= 0 and node_robot[prev] == node_robot[y] and low[y] < low[prev]:
            low[prev] = low[y]
            if not waiting[prev]:
                waiting[prev] = True
                stack[top] = prev
                top += 1
        for f in range(in_ptr[y], in_ptr[y + 1]):
            p = in_src[f]
            if enabled[in_side[f]] and low[y] < low[p]:
                low[p] = low[y]
                if not waiting[p]:
                    waiting[p] = True
                    stack[top] = p
                    top += 1


def first_come(ctx: FlipContext) -> bool:
    """BTPG's online rule as a flip test: a robot stopped by a switchable obstacle that its
    label robot has not reached yet takes it (always ``True``; the executor offers only
    switchable, unsettled obstacles whose other robot is before them, and settles each once)."""
    return True
