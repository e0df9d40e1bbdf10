"""Optimal passing orders within a horizon: a best-first search over the open obstacles' labels.

A reimplementation, from the published descriptions, of the idea shared by the
*switchable action dependency graph* (SADG; Berndt, van Duijkeren, Palmieri, Lindemann &
Kober, IEEE T-RO 2024: choose the switchable dependencies by a receding-horizon
optimisation) and *switchable-edge search* (Feng, Li, Koenig et al., ICAPS 2024: a
best-first search over the orientations of switchable edges whose lower bound is the cost
with the unsettled edges left out), on the segment graph of the label-flipping deadlock
paper (2021, Definition 3, exact resolution of :mod:`.segment_graph`). No code of the
authors was used; where this differs from them is said below.

When it decides (:class:`OptimalOrders`)
    Every ``period`` steps, and at once when a robot is stopped at an obstacle whose order
    may still change (each obstacle calls once, as a flip test is tried once).
What it decides
    An obstacle is *relabellable* when neither robot starts or ends in it
    (:func:`.btpg.statically_switchable`) and its label robot has not reached it
    (``x_ℓ < B_ℓ``, the family's condition for a safe flip; the other robot then has not
    entered it either). The *open* obstacles are the relabellable ones with a robot at most
    ``horizon`` steps from them, at most ``max_open`` of them, nearest first; the other
    relabellable ones are *deferred*: they will be decided when they come within the
    horizon, and until then they are left out of the schedule below (their waits are not
    anticipated). Every other obstacle keeps its label and its edges. Among all labelings
    of the open obstacles the search returns one that minimises the **expected remaining
    travel time**, the sum over robots of the expected arrival times in the
    *expected-duration schedule* of the active segment graph:

    ``E(v) = max(E(v⁻) + τ_r(s(v⁻) → s(v)),  max_{u → v} E(u) + τ_r(s(v) − 1 → s(v)))``,

    ``v⁻`` the robot's previous vertex (its current step at the current time for the
    first vertex not yet entered), ``u → v`` the active label edges from vertices not yet
    entered, ``τ_r(a → b) = Σ_{k=a}^{b−1} Δ / (1 − p(π_r(k)))`` the expected duration of
    robot ``r``'s steps (the flip tests' model, :mod:`.label_flipping`), and the arrival
    ``E(goal vertex) + τ_r(→ K_r)``. A labeling that closes a cycle has no schedule
    (infinite cost): it is never chosen.
The search (:func:`solve_orders`, compiled)
    Best-first over partial labelings. A node's bound is the schedule's cost with only
    its settled open obstacles' edges (the unsettled ones left out): adding edges never
    makes a vertex earlier, so the bound never exceeds the cost of any completion
    (admissible and monotone). A node is *complete* when every unsettled open obstacle
    is already respected by the schedule in one orientation (all the edges of one label
    hold with the schedule's times); settling each that way changes no time, so the
    node's bound is its cost, and since each edge ``u → v`` holds with ``E(v) > E(u)``
    that labeling is acyclic. Otherwise the search branches on the violated obstacle whose
    robots are due first. The first complete node taken from the queue is optimal.
    Budget: at most ``node_budget`` expansions (a count, for identical runs on every
    machine). The incumbent starts as the current labels and is improved at every
    expansion by completing the node first come, first served (each violated obstacle
    for the robot the schedule has due first); when the budget runs out the incumbent
    is returned.
Applying the choice
    The chosen flips are made one by one in the whole segment graph (deferred obstacles
    included, at their labels) with the incremental cycle test of :mod:`.segment_graph`;
    a flip that would close a cycle through a deferred obstacle is not made. If that cut
    leaves a labeling costlier than the current one, every flip is undone.
Guarantee
    (1) *Never worse than the orders it started from on the instance it solved* (the
    model above): the incumbent starts as the current labels with their cost, only a
    labeling of strictly lower cost replaces it, and a labeling cut back when applied is
    kept only if it is still no costlier. (2) *Exact within the budget*: when the search
    ends before the budget, the labeling is optimal among all labelings of the open
    obstacles for the model. (3) *No collision*: labels change only on relabellable
    obstacles, whose new label robot's invariant (Eq. 1) holds trivially because the
    other robot has not reached them. (4) *No cycle*: every flip is made with the cycle
    test of the whole graph, so the active segment graph never holds a cycle and, by
    Theorems 1–2, no deadlock happens when the plan is non-conflicting (Definition 4).
Deviations from the papers
    SADG solves a MILP over a horizon and switchable-edge search optimises the sum of
    costs of a MAPF temporal plan graph with unit durations; here durations are the
    expected step times under the disturbance model and the objective is the sum of
    expected arrival times of the expected-duration schedule (the certainty-equivalent,
    not the expectation of the maxima); deferred obstacles are left out of it; the search
    is budgeted, so at scale it is mostly its first-come completion that decides.
Complexity
    A decision builds the root schedule once (``O(V + E)`` over the vertices not entered,
    compiled) and then adds obstacles one at a time: a cycle test that only enters
    vertices not later than the new edge's tail, and a rise of the times that only visits
    the vertices whose time rises; each node is built on the one root schedule and undone
    from a log. At most ``node_budget`` expansions, each one completion and two children.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numba
import numpy as np

from .btpg import label_edge_csr, plan_sides, statically_switchable
from .coordination_space import CoordinationSpace
from .options import OptimalSettings
from .segment_graph import IncrementalCycleDetector, SegmentLayout

SATISFIED_TOLERANCE = 1e-9
"""Seconds of slack when testing whether a schedule respects an edge."""


@dataclass(frozen=True)
class OrderGraph:
    """The segment layout as the schedule kernels read it (built once per plan)."""

    node_robot: np.ndarray
    node_start: np.ndarray
    goal_node: np.ndarray
    out_ptr: np.ndarray
    out_dst: np.ndarray
    out_side: np.ndarray
    in_ptr: np.ndarray
    in_src: np.ndarray
    in_side: np.ndarray
    side_ptr: np.ndarray
    edge_src: np.ndarray
    edge_dst: np.ndarray
    lengths: np.ndarray

    @classmethod
    def of(cls, layout: SegmentLayout, space: CoordinationSpace) -> OrderGraph:
        out_ptr, out_dst, out_side = label_edge_csr(layout, by="src")
        in_ptr, in_src, in_side = label_edge_csr(layout, by="dst")
        n = space.n_robots
        starts = layout.node_start.astype(np.intp)
        robots = layout.node_robot.astype(np.intp)
        # each robot's last vertex at or before its goal step (a vertex past it is where another robot waits for it to leave)
        span = max(int(starts.max(initial=0)), int(space.lengths.max(initial=0))) + 2
        keys = robots * span + starts
        goal_node = np.searchsorted(keys, np.arange(n) * span + space.lengths, side="right") - 1
        return cls(robots, starts, goal_node.astype(np.intp), out_ptr, out_dst, out_side, in_ptr, in_src, in_side,
                   np.searchsorted(layout.edge_side, np.arange(2 * space.n_obstacles + 1)).astype(np.intp),
                   layout.edge_src.astype(np.intp), layout.edge_dst.astype(np.intp), space.lengths.astype(np.intp))

    @property
    def n_nodes(self) -> int:
        return int(len(self.node_robot))


@dataclass(frozen=True)
class Solution:
    """What :func:`solve_orders` decided.

    Attributes
    ----------
    labels:
        ``(m,)`` every obstacle's label after the decision.
    open:
        the open obstacles that were decided.
    cost, start_cost:
        expected remaining travel time (s, summed over robots) of the chosen labels and of
        the labels the decision started from (``cost ≤ start_cost``).
    bound:
        the lowest bound left in the queue (``cost`` when the search proved optimality).
    expansions:
        best-first expansions made.
    exhausted:
        the node budget ran out before optimality was proved.
    reverted:
        the chosen labels would have closed a cycle through a deferred obstacle in the
        whole segment graph: the current labels were kept.
    """

    labels: np.ndarray
    open: np.ndarray
    cost: float
    start_cost: float
    bound: float
    expansions: int
    exhausted: bool
    reverted: bool = False


def expected_step_times(probability: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-step expected durations ``Δ / (1 − p)`` ``(n, K_max + 2)`` (the last step repeated,
    for vertices one step past a goal) and their cumulative sums ``(n, K_max + 3)``."""
    p = np.concatenate([probability, probability[:, -1:]], axis=1)
    step = dt / (1.0 - p)
    return step, np.concatenate([np.zeros((len(step), 1)), np.cumsum(step, axis=1)], axis=1)


def open_obstacles(space: CoordinationSpace, labels: np.ndarray, progress: np.ndarray, closed: np.ndarray,
                   horizon: int, max_open: int) -> tuple[np.ndarray, np.ndarray]:
    """The open obstacles (see the module docstring) and the deferred ones.

    Returns the indices of at most ``max_open`` open obstacles, those whose nearer robot is
    fewest steps away (ties: lower index), in that order, and the ``(m,)`` mask of the
    *deferred* obstacles: relabellable (not ``closed``, label robot before them) but not
    open now. ``closed`` ``(m,)`` marks obstacles that may not be relabelled (neither robot
    may hold them, or a caller such as the supervisor cannot vouch that the label robot is
    before them).
    """
    if space.n_obstacles == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=bool)
    side = plan_sides(space, labels)
    waiter, holder = space.side_waiter[side], space.side_other[side]
    holder_first, waiter_first = space.side_other_lo[side], space.side_lo[side]
    relabellable = ~closed & (progress[holder] < holder_first)
    distance = np.minimum(waiter_first - progress[waiter], holder_first - progress[holder])
    candidates = np.flatnonzero(relabellable & (distance <= horizon))
    chosen = candidates[np.argsort(distance[candidates], kind="stable")][:max_open]
    deferred = relabellable.copy()
    deferred[chosen] = False
    return chosen, deferred


class ScheduleModel:
    """The expected-duration schedule of one decision (see the module docstring).

    The *root* schedule leaves the open and the deferred obstacles out (one full
    evaluation, :func:`_evaluate_root`); a labeling's schedule adds the chosen side of each
    settled open obstacle to it, one obstacle at a time (:func:`_extend`): a cycle test
    bounded by the times, then only the vertices whose time rises are updated. Every
    schedule, partial or complete, is therefore the earliest one of its graph, whatever the
    order in which the obstacles were added.

    Parameters
    ----------
    graph:
        the plan's :class:`OrderGraph`.
    space:
        its coordination space.
    labels:
        the current labels (those of the open obstacles are decided).
    progress:
        ``(n,)`` the robots' plan steps now.
    now:
        the current time (s).
    step, cumulative:
        :func:`expected_step_times`.
    arrived:
        ``(n,)`` arrival time (s) of the robots already at their goals (others ignored).
    open_ids:
        the open obstacles.
    deferred:
        ``(m,)`` obstacles left out of the schedule: they will be decided when they come
        within the horizon (``None``: none).
    """

    def __init__(self, graph: OrderGraph, space: CoordinationSpace, labels: np.ndarray, progress: np.ndarray, now: float,
                 step: np.ndarray, cumulative: np.ndarray, arrived: np.ndarray, open_ids: np.ndarray,
                 deferred: np.ndarray | None = None):
        self.graph, self.space = graph, space
        self.x = np.ascontiguousarray(progress, dtype=np.intp)
        self.now, self.step, self.cumulative = float(now), step, cumulative
        self.arrived = np.asarray(arrived, dtype=float)
        self.open = np.asarray(open_ids, dtype=np.intp)
        g = graph
        self.done = self.x[g.node_robot] >= g.node_start
        base = np.zeros(2 * space.n_obstacles, dtype=np.uint8)
        base[plan_sides(space, labels)] = 1
        left_out = np.concatenate([self.open, np.flatnonzero(deferred) if deferred is not None else np.zeros(0, dtype=np.intp)])
        base[2 * left_out] = 0
        base[2 * left_out + 1] = 0
        self.base = base
        self.current = np.where(labels[self.open] == space.robot_i[self.open], 1, 0).astype(np.int8)
        self.root_times = np.full(g.n_nodes, -np.inf)
        if not _evaluate_root(self.x, self.now, cumulative, step, g.node_robot, g.node_start, g.out_ptr, g.out_dst, g.out_side,
                              g.in_ptr, g.in_src, g.in_side, base, self.done, self.root_times):
            raise RuntimeError("segment graph: expected an acyclic active subgraph for the current labels, received a cycle")
        self.edges = self._edges_of_open()
        # scratch of the compiled searches: visit stamps (and the stamp in use), a stack/queue, queue flags
        self.scratch = (np.zeros(g.n_nodes, dtype=np.int64), np.zeros(1, dtype=np.int64), np.empty(g.n_nodes, dtype=np.intp),
                        np.zeros(g.n_nodes, dtype=np.bool_))
        self.log = new_log(g.n_nodes, 4)

    def _edges_of_open(self) -> tuple[np.ndarray, ...]:
        """Per open obstacle ``k`` and orientation ``c`` (active side ``2o + c``), its edges
        ``(row = 2k + c, src, dst, weight)`` and ``entry`` ``(k, 2)``, the first head vertex
        (where the waiter of that orientation is due)."""
        g = self.graph
        sides = (2 * self.open[:, None] + np.arange(2)[None, :]).ravel()
        lo, hi = g.side_ptr[sides], g.side_ptr[sides + 1]
        row = np.repeat(np.arange(len(sides)), hi - lo).astype(np.intp)
        index = np.arange(int((hi - lo).sum())) - np.repeat(np.cumsum(hi - lo) - (hi - lo) - lo, hi - lo)
        src, dst = g.edge_src[index], g.edge_dst[index]
        weight = self.step[g.node_robot[dst], g.node_start[dst] - 1]
        entry = np.full(len(sides), np.iinfo(np.intp).max, dtype=np.intp)
        np.minimum.at(entry, row, dst)
        return row, src, dst, weight, entry.reshape(-1, 2)

    @property
    def arrays(self) -> tuple:
        """What the compiled schedule functions read, in their order."""
        g = self.graph
        return (g.node_robot, g.node_start, g.out_ptr, g.out_dst, g.out_side, g.side_ptr, g.edge_src, g.edge_dst,
                self.done, self.cumulative, self.step, *self.scratch)

    @property
    def costing(self) -> tuple:
        """What :func:`_cost` reads besides the times."""
        g = self.graph
        return self.x, self.now, self.cumulative, self.arrived, g.goal_node, g.lengths, g.node_start

    def schedule(self, choice: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """``(times, enabled)`` of the partial labeling ``choice`` (``-1``: left out, ``c``: side
        ``2o + c`` active), or ``None`` when it closes a cycle."""
        times, enabled = self.root_times.copy(), self.base.copy()
        ok = _settle(times, enabled, np.asarray(choice, dtype=np.int8), self.open, self.arrays, self.log)
        self.log[3][0] = self.log[7][0] = 0  # nothing to undo: the copies are the caller's
        return (times, enabled) if ok else None

    def cost(self, times: np.ndarray) -> float:
        """Sum over robots of the expected arrival time (s)."""
        return float(_cost(times, self.costing))

    def respected(self, times: np.ndarray) -> np.ndarray:
        """``(k, 2)`` bool: the schedule respects every edge of orientation ``c`` of open obstacle ``k``."""
        return _respected(times, len(self.open), self.edges)


def solve_orders(model: ScheduleModel, budget: int) -> tuple[np.ndarray, float, float, float, int, bool]:
    """Best-first search of the module docstring on one decision's model (compiled, :func:`_search`).

    Returns the chosen orientation per open obstacle ``(k,)`` (``c``: side ``2o + c`` active),
    its cost, the cost of the current labels, the lowest bound left, the expansions made and
    whether the budget ran out.
    """
    times, enabled = model.root_times.copy(), model.base.copy()
    choice, cost, start_cost, bound, expansions, exhausted = _search(
        model.current, int(budget), model.open, times, enabled, model.arrays, model.costing, model.edges, model.log)
    if expansions < 0:
        raise RuntimeError("segment graph: expected acyclic current labels, received a cycle")
    return choice, float(cost), float(start_cost), float(bound), int(expansions), bool(exhausted)


@numba.njit(cache=True)
def _search(current, budget, open_ids, times, enabled, arrays, costing, edges, log):
    """The best-first search of the module docstring.

    Nodes are partial labelings (rows of ``choices``: ``-1`` unsettled), queued by their
    bound (ties: first generated). One schedule is kept, the root's (``times``,
    ``enabled``): a node's schedule is built on it in place and undone afterwards
    (:func:`_begin`, :func:`_rollback`), so only the vertices whose times change are
    touched. Returns ``(choice, cost, start_cost, bound, expansions, exhausted)``;
    ``expansions = -1`` when the current labels close a cycle."""
    k = len(open_ids)
    root_cost = _cost(times, costing)
    saved = _begin(log)
    ok = _settle(times, enabled, current, open_ids, arrays, log)
    start_cost = _cost(times, costing)
    _rollback(times, enabled, log, saved)
    if not ok:
        return current.copy(), np.inf, np.inf, np.inf, -1, False
    best, best_cost = current.copy(), start_cost
    choices = np.full((2 * budget + 2, k), -1, dtype=np.int8)
    queue = [(root_cost, 0)]
    rows, expansions = 1, 0
    while len(queue) > 0:
        bound, row = heapq.heappop(queue)
        if bound >= best_cost - SATISFIED_TOLERANCE:
            return best, best_cost, start_cost, best_cost, expansions, False
        choice = choices[row].copy()
        node = _begin(log)
        _settle(times, enabled, choice, open_ids, arrays, log)
        respected = _respected(times, k, edges)
        pick, first_due, violated = _branching(times, choice, respected, edges[4])
        if pick < 0:  # every unsettled obstacle is respected one way: settling it so changes no time
            _rollback(times, enabled, log, node)
            for j in range(k):
                if choice[j] < 0:
                    choice[j] = 0 if respected[j, 0] else 1
            return choice, bound, start_cost, bound, expansions, False
        if expansions >= budget:
            _rollback(times, enabled, log, node)
            return best, best_cost, start_cost, bound, expansions, True
        expansions += 1
        completion, completion_cost = _complete(times, enabled, choice, first_due, open_ids, arrays, costing, edges, log)
        if completion_cost < best_cost - SATISFIED_TOLERANCE:
            best, best_cost = completion, completion_cost
        for c in range(2):
            child = _begin(log)
            if _extend(times, enabled, 2 * open_ids[pick] + c, arrays, log):
                child_bound = _cost(times, costing)
                if child_bound < best_cost - SATISFIED_TOLERANCE:
                    choices[rows] = choice
                    choices[rows, pick] = c
                    heapq.heappush(queue, (child_bound, rows))
                    rows += 1
            _rollback(times, enabled, log, child)
        _rollback(times, enabled, log, node)
    return best, best_cost, start_cost, best_cost, expansions, False


@numba.njit(cache=True)
def _branching(times, choice, respected, entry):
    """The violated unsettled obstacle whose robots are due first (``-1`` when none), the
    orientation giving priority to the robot due first for every obstacle, and the number
    of violated unsettled obstacles."""
    k = len(choice)
    first_due = np.zeros(k, dtype=np.int8)
    pick, soonest, violated = -1, np.inf, 0
    for j in range(k):
        due0, due1 = times[entry[j, 0]], times[entry[j, 1]]
        first_due[j] = 0 if due1 < due0 else 1  # robot j (waiter of orientation 1) due first: label j, orientation 0
        if choice[j] >= 0 or respected[j, 0] or respected[j, 1]:
            continue
        violated += 1
        if min(due0, due1) < soonest:
            pick, soonest = j, min(due0, due1)
    return pick, first_due, violated


@numba.njit(cache=True)
def _complete(times, enabled, choice, orientation, open_ids, arrays, costing, edges, log):
    """Complete the partial labeling ``choice`` (schedule ``times``, ``enabled``; both are
    restored): add each unsettled obstacle the schedule violates as ``orientation`` says,
    until the schedule respects every remaining one, which is then settled the way it is
    respected (that changes no time). Returns the labeling and its cost (``inf`` on a cycle)."""
    k = len(choice)
    choice = choice.copy()
    saved = _begin(log)
    cost = np.inf
    while True:
        respected = _respected(times, k, edges)
        added, cycle = False, False
        for j in range(k):
            if choice[j] >= 0 or respected[j, 0] or respected[j, 1]:
                continue
            if not _extend(times, enabled, 2 * open_ids[j] + orientation[j], arrays, log):
                cycle = True
                break
            choice[j] = orientation[j]
            added = True
        if cycle:
            break
        if not added:
            for j in range(k):
                if choice[j] < 0:
                    choice[j] = 0 if respected[j, 0] else 1
            cost = _cost(times, costing)
            break
    _rollback(times, enabled, log, saved)
    return choice, cost


@numba.njit(cache=True)
def _settle(times, enabled, choice, open_ids, arrays, log):
    """Add the settled obstacles of ``choice`` to the schedule in place (logged); ``False`` on a cycle."""
    for j in range(len(choice)):
        if choice[j] >= 0 and not _extend(times, enabled, 2 * open_ids[j] + choice[j], arrays, log):
            return False
    return True


@numba.njit(cache=True)
def _cost(times, costing):
    """Sum over robots of the expected arrival time: the goal vertex's time plus the rest of
    the way, from now for a robot past its goal vertex, the recorded arrival for a finished one."""
    x, now, cumulative, arrived, goal_node, lengths, node_start = costing
    total = 0.0
    for r in range(len(x)):
        if x[r] >= lengths[r]:
            total += arrived[r]
            continue
        goal = goal_node[r]
        rest = cumulative[r, lengths[r]]
        if x[r] >= node_start[goal]:
            total += now + rest - cumulative[r, x[r]]
        else:
            total += times[goal] + rest - cumulative[r, node_start[goal]]
    return total


@numba.njit(cache=True)
def _respected(times, k, edges):
    """``(k, 2)``: the schedule respects every edge of orientation ``c`` of open obstacle ``k``."""
    row, src, dst, weight, _ = edges
    ok = np.ones((k, 2), dtype=np.bool_)
    for e in range(len(row)):
        if times[dst[e]] < times[src[e]] + weight[e] - SATISFIED_TOLERANCE:
            ok[row[e] // 2, row[e] % 2] = False
    return ok


@numba.njit(cache=True)
def _extend(times, enabled, side, arrays, log):
    """Add ``side``'s edges to the schedule ``times`` and to ``enabled`` (in place, logged in
    the open transaction of ``log``); ``False`` (nothing changed) when they close a cycle."""
    node_robot, node_start, out_ptr, out_dst, out_side, side_ptr, edge_src, edge_dst, done, cumulative, step, stamp, mark, \
        scratch, queued = arrays
    mark[0] += 1
    if _closes_cycle(side, side_ptr, edge_src, edge_dst, times, done, mark[0], stamp, scratch, node_robot, out_ptr, out_dst,
                     out_side, enabled):
        return False
    sides, side_top = log[6], log[7]
    enabled[side] = 1
    sides[side_top[0]] = side
    side_top[0] += 1
    _raise_times(side, side_ptr, edge_src, edge_dst, times, done, scratch, queued, cumulative, step, node_robot, node_start,
                 out_ptr, out_dst, out_side, enabled, log)
    return True


def new_log(n_nodes: int, depth: int) -> tuple:
    """An undo log for transactions nested ``depth`` deep: each vertex is logged once per
    transaction (``3 · depth · V`` slots suffice), and the sides enabled in each."""
    slots = depth * n_nodes
    return (np.empty(slots, dtype=np.intp), np.empty(slots), np.empty(slots, dtype=np.int64), np.zeros(1, dtype=np.intp),
            np.zeros(2, dtype=np.int64), np.zeros(n_nodes, dtype=np.int64), np.empty(slots, dtype=np.intp),
            np.zeros(1, dtype=np.intp))


@numba.njit(cache=True)
def _set(times, y, value, log):
    """``times[y] = value``, logging the old value the first time ``y`` changes in the open transaction."""
    nodes, values, owners, top, transaction, owner = log[0], log[1], log[2], log[3], log[4], log[5]
    if owner[y] != transaction[0]:
        nodes[top[0]], values[top[0]], owners[top[0]] = y, times[y], owner[y]
        top[0] += 1
        owner[y] = transaction[0]
    times[y] = value


@numba.njit(cache=True)
def _begin(log):
    """Open a transaction; returns what :func:`_rollback` needs to undo it."""
    top, transaction, side_top = log[3], log[4], log[7]
    saved = (top[0], transaction[0], side_top[0])
    transaction[1] += 1
    transaction[0] = transaction[1]
    return saved


@numba.njit(cache=True)
def _rollback(times, enabled, log, saved):
    """Undo every change since :func:`_begin` returned ``saved`` (innermost transaction first)."""
    nodes, values, owners, top, transaction, owner, sides, side_top = log
    while top[0] > saved[0]:
        top[0] -= 1
        y = nodes[top[0]]
        times[y] = values[top[0]]
        owner[y] = owners[top[0]]
    while side_top[0] > saved[2]:
        side_top[0] -= 1
        enabled[sides[side_top[0]]] = 0
    transaction[0] = saved[1]


@numba.njit(cache=True)
def _closes_cycle(side, side_ptr, edge_src, edge_dst, times, done, mark, stamp, stack, node_robot, out_ptr, out_dst, out_side,
                  enabled):
    """Would the edges of ``side`` close a cycle in the graph ``enabled`` whose earliest
    schedule is ``times``? Only a violated edge ``u → v`` can (a satisfied one keeps
    ``times`` a valid potential), and then ``u`` is reachable from ``v``; along any path
    ``times`` grows, so the search enters only vertices not later than ``u``. The side's
    heads lie on one robot's path and its tails on the other's, in step order, so the
    searches from later heads are reused by earlier ones (as in :mod:`.btpg`)."""
    v = len(node_robot)
    for e in range(side_ptr[side + 1] - 1, side_ptr[side] - 1, -1):
        head, tail = edge_dst[e], edge_src[e]
        if done[head] or done[tail]:
            continue
        limit = times[tail]
        if stamp[head] != mark and times[head] <= limit:
            top = 0
            stamp[head] = mark
            stack[top] = head
            top += 1
            while top > 0:
                top -= 1
                y = stack[top]
                nxt = y + 1
                if nxt < v and node_robot[nxt] == node_robot[y] and stamp[nxt] != mark and not done[nxt] and times[nxt] <= limit:
                    stamp[nxt] = mark
                    stack[top] = nxt
                    top += 1
                for f in range(out_ptr[y], out_ptr[y + 1]):
                    z = out_dst[f]
                    if enabled[out_side[f]] and stamp[z] != mark and not done[z] and times[z] <= limit:
                        stamp[z] = mark
                        stack[top] = z
                        top += 1
        if stamp[tail] == mark:
            return True
    return False


@numba.njit(cache=True)
def _rise(w, rise, times, log, queue, queued, head, count):
    """Raise vertex ``w``'s time to ``rise`` if that is later (logged), queueing it unless it
    waits already; returns the queue's new length."""
    if rise > times[w]:
        _set(times, w, rise, log)
        if not queued[w]:
            queued[w] = True
            queue[(head + count) % len(queue)] = w
            count += 1
    return count


@numba.njit(cache=True)
def _raise_times(side, side_ptr, edge_src, edge_dst, times, done, queue, queued, cumulative, step, node_robot, node_start, out_ptr,
                 out_dst, out_side, enabled, log):
    """Raise ``times`` to the earliest schedule of ``enabled`` (which now holds ``side``):
    start from the heads the side's edges push later and carry each rise forward
    (label-correcting, FIFO; a vertex waits in the queue at most once at a time). The graph
    is acyclic (tested first), so it ends; only vertices whose time rises are visited, and
    each change is logged for :func:`_rollback`."""
    v = len(node_robot)
    capacity = len(queue)
    head, count = 0, 0
    for e in range(side_ptr[side], side_ptr[side + 1]):
        u, w = edge_src[e], edge_dst[e]
        if done[u] or done[w]:
            continue
        count = _rise(w, times[u] + step[node_robot[w], node_start[w] - 1], times, log, queue, queued, head, count)
    while count > 0:
        y = queue[head]
        head = (head + 1) % capacity
        count -= 1
        queued[y] = False
        r = node_robot[y]
        nxt = y + 1
        if nxt < v and node_robot[nxt] == r and not done[nxt]:
            count = _rise(nxt, times[y] + cumulative[r, node_start[nxt]] - cumulative[r, node_start[y]], times, log, queue, queued,
                          head, count)
        for f in range(out_ptr[y], out_ptr[y + 1]):
            z = out_dst[f]
            if not enabled[out_side[f]] or done[z]:
                continue
            count = _rise(z, times[y] + step[node_robot[z], node_start[z] - 1], times, log, queue, queued, head, count)


@numba.njit(cache=True)
def _evaluate_root(x, now, cumulative, step, node_robot, node_start, out_ptr, out_dst, out_side, in_ptr, in_src, in_side,
                   enabled, done, times):
    """Earliest expected times of every vertex not entered (the formula of the module
    docstring) into ``times``, by Kahn's order; ``False`` when they hold a cycle.
    ``O(V + E)``."""
    v = len(node_robot)
    indegree = np.zeros(v, dtype=np.intp)
    members = 0
    for y in range(v):
        if done[y]:
            continue
        members += 1
        r = node_robot[y]
        prev = y - 1
        if prev >= 0 and node_robot[prev] == r and not done[prev]:
            indegree[y] += 1
            times[y] = -np.inf
        else:  # the robot's first vertex not entered: from where it stands now
            times[y] = now + cumulative[r, node_start[y]] - cumulative[r, x[r]]
        for e in range(in_ptr[y], in_ptr[y + 1]):
            if enabled[in_side[e]] and not done[in_src[e]]:
                indegree[y] += 1
    queue = np.empty(members, dtype=np.intp)
    head, tail = 0, 0
    for y in range(v):
        if not done[y] and indegree[y] == 0:
            queue[tail] = y
            tail += 1
    while head < tail:
        y = queue[head]
        head += 1
        r = node_robot[y]
        nxt = y + 1
        if nxt < v and node_robot[nxt] == r and not done[nxt]:
            times[nxt] = max(times[nxt], times[y] + cumulative[r, node_start[nxt]] - cumulative[r, node_start[y]])
            indegree[nxt] -= 1
            if indegree[nxt] == 0:
                queue[tail] = nxt
                tail += 1
        for e in range(out_ptr[y], out_ptr[y + 1]):
            w = out_dst[e]
            if not enabled[out_side[e]] or done[w]:
                continue
            times[w] = max(times[w], times[y] + step[node_robot[w], node_start[w] - 1])
            indegree[w] -= 1
            if indegree[w] == 0:
                queue[tail] = w
                tail += 1
    return tail == members


class OptimalOrders:
    """The ``optimal`` method's per-run decisions (see the module docstring).

    Parameters
    ----------
    space, layout:
        the plan's coordination space and its exact segment layout.
    settings:
        horizon, node budget and decision period.
    dt:
        seconds per step.
    detector:
        the cycle test of the current labels (default: a new one on the plan labels; the
        supervisor passes its own after a plan change).
    """

    def __init__(self, space: CoordinationSpace, layout: SegmentLayout, settings: OptimalSettings, dt: float,
                 detector: IncrementalCycleDetector | None = None):
        self.space, self.settings, self.dt = space, settings, float(dt)
        self.graph = OrderGraph.of(layout, space)
        self.fixed = ~statically_switchable(space)
        self.called = np.zeros(space.n_obstacles, dtype=bool)
        self.detector = IncrementalCycleDetector(layout, space.initial_labels) if detector is None else detector
        self._times: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def due(self, t: int) -> bool:
        """Whether step ``t`` is a periodic decision step."""
        return t % self.settings.period == 0

    def next_decision(self, t: int) -> int:
        """The first periodic decision step after ``t``."""
        return (t // self.settings.period + 1) * self.settings.period

    def quiet(self, closed: np.ndarray) -> np.ndarray:
        """``(m,)`` obstacles at which a stopped robot calls no decision: fixed ones, ``closed``
        ones and those that have called one already (what the compiled plain steps test)."""
        return self.fixed | closed | self.called

    def call(self, blocking: np.ndarray, progress: np.ndarray, closed: np.ndarray) -> bool:
        """Whether a robot stopped by a blocking side (``(2m,)`` mask) of an obstacle that may
        still be relabelled (its label robot before it) calls a decision now; each obstacle calls once."""
        s = self.space
        sides = np.flatnonzero(blocking)
        obstacle = sides // 2
        calls = ~self.quiet(closed)[obstacle] & (progress[s.side_other[sides]] < s.side_other_lo[sides])
        self.called[obstacle[calls]] = True
        return bool(calls.any())

    def decide(self, labels: np.ndarray, progress: np.ndarray, closed: np.ndarray, t: int, probability: np.ndarray,
               arrival_steps: np.ndarray) -> Solution | None:
        """Choose the open obstacles' labels at step ``t`` (``None`` when none is open).

        ``closed`` marks obstacles not to relabel beyond the fixed ones; ``probability``
        ``(n, K_max + 1)`` the disturbance probabilities the expected durations use;
        ``arrival_steps`` the arrival step of finished robots.
        """
        open_ids, deferred = open_obstacles(self.space, labels, progress, self.fixed | closed, self.settings.horizon,
                                            self.settings.max_open)
        if len(open_ids) == 0:
            return None
        step, cumulative = self.expected_times(probability)
        model = ScheduleModel(self.graph, self.space, labels, progress, t * self.dt, step, cumulative,
                              np.where(arrival_steps >= 0, arrival_steps, 0) * self.dt, open_ids, deferred)
        choice, cost, start_cost, bound, expansions, exhausted = solve_orders(model, self.settings.node_budget)
        applied = self.apply_acyclic(model, labels, choice, progress)
        if not np.array_equal(applied, choice):  # a flip would have closed a cycle through a deferred obstacle
            kept = model.schedule(applied)
            cost = model.cost(kept[0]) if kept is not None else float("inf")
            if cost > start_cost:  # never worse than the labels it started from
                self.apply_acyclic(model, self.labels_of(model, labels, applied), model.current, progress)
                applied, cost = model.current.copy(), start_cost
        return Solution(self.labels_of(model, labels, applied), open_ids, cost, start_cost, bound, expansions, exhausted,
                        not np.array_equal(applied, choice))

    def expected_times(self, probability: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`expected_step_times` of ``probability``, kept while the same table is passed."""
        if self._times is None or self._times[0] is not probability:
            self._times = (probability, *expected_step_times(probability, self.dt))
        return self._times[1], self._times[2]

    def labels_of(self, model: ScheduleModel, labels: np.ndarray, choice: np.ndarray) -> np.ndarray:
        """``labels`` with the open obstacles oriented as ``choice``."""
        new = labels.copy()
        o = model.open
        new[o] = np.where(choice == 1, self.space.robot_i[o], self.space.robot_j[o])
        return new

    def apply_acyclic(self, model: ScheduleModel, labels: np.ndarray, choice: np.ndarray, progress: np.ndarray) -> np.ndarray:
        """Relabel the open obstacles from ``labels`` towards ``choice`` in the whole segment
        graph (deferred obstacles included, at their labels), most urgent first, each flip
        with the incremental cycle test; a flip that would close a cycle is not made.
        Returns the orientations made."""
        made = np.where(labels[model.open] == self.space.robot_i[model.open], 1, 0).astype(np.int8)
        for k in np.flatnonzero(made != choice).tolist():
            o = int(model.open[k])
            label = int(self.space.robot_i[o] if choice[k] == 1 else self.space.robot_j[o])
            if self.detector.try_flip(o, label, progress):
                made[k] = choice[k]
        return made
