"""The whole search loop of Fig. 4 as compiled code: steps 1–8 of many steps in one call.

A Fig. 7 run moves a handful of robots on ~10² vertices for a few dozen steps; each phase
of a step is a few microseconds of work, so a loop that returns to Python between the
phases spends most of its time in the calls. :func:`run_steps` runs the loop of
:class:`~robofleet.search.simulation.SearchBatch` — choose (steps 4–5), move (step 6),
observe (failures, steps 1–3, 7 and 8) — for a block of steps without leaving compiled
code, calling the per-phase kernels of :mod:`robofleet.search.step_kernels`, :mod:`robofleet.search.knowledge` and
:mod:`robofleet.search.neighbours`:

* the random draws come from the robots' own streams
  (:class:`~robofleet.search.policy.RobotStreams`), drawn a block of
  :attr:`~robofleet.search.policy.RobotStreams.chunk` steps at a time (LFP's normals
  before its uniforms); a call runs steps of one block, and step ``k`` reads column
  ``k mod chunk``, so the draws of a step do not depend on how steps are grouped into calls;
* the numbers numpy computes with its own vectorized routines (``arctan2`` of an edge's
  direction, the power in Mantegna's step length) are looked up in tables numpy made;
* events are returned as rows ``(step, kind, a, b, c, time)`` (:data:`EVENT_KINDS`) in
  the order the phases emit them, and the recorded rows (vertices and the clock after
  each step) as arrays.

The arrays of the batch are passed as three named tuples: :class:`LoopTables` (the grid
and sensing tables, read only), :class:`LoopParameters` (scalars) and :class:`LoopState`
(everything a step changes, changed in place).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numba import types
from numba.typed import List

from .knowledge import _exchange, _frontier_empty, _not_in_sorted, set_bit
from .neighbours import _collision_pairs, _pairs_within
from .step_kernels import advance_clocks, levy_choices, may_collide, random_unvisited_choices, sense_and_record, sequential_choices

SEQUENTIAL, RANDOM_UNVISITED, LEVY = 0, 1, 2
"""Policy codes of :attr:`LoopParameters.policy`."""
EVENT_KINDS = ("failure", "failure_detected", "target_found", "stop", "obstacle_collision", "collision")
"""Event kinds by code; the fields ``a, b, c`` of a row of each kind are: ``failure``
(robot, vertex), ``failure_detected`` (robot, failed), ``target_found`` (robot, target),
``stop`` (robot, 1 for its own rule, 0 for a received stop), ``obstacle_collision``
(robot, vertex), ``collision`` (robot i, robot j, vertex)."""
FAILURE, FAILURE_DETECTED, TARGET_FOUND, STOP, OBSTACLE_COLLISION, COLLISION = range(6)
SMALL_TEAM = 32
"""Teams up to this size check a move for collisions pair by pair before sorting."""
EVENT = types.Tuple((types.int64, types.int64, types.int64, types.int64, types.int64, types.float64))
glue = numba.njit(cache=True, inline="always")
"""The phases below are inlined into :func:`run_steps` at numba's level (one compiled
function, whose call sites pass one set of argument types), rather than compiled each on
its own: a separately compiled callee is linked into, optimized and emitted again with
every caller up the tree, and the tuples of arrays they share make each copy large."""


class LoopTables(NamedTuple):
    """Per-vertex tables of the grid and the sensing (see :mod:`.grids`, :mod:`.sensing`)."""

    points: np.ndarray
    candidates: np.ndarray
    neighbours: np.ndarray
    edge_ok: np.ndarray
    words: np.ndarray
    masks: np.ndarray
    sensed_ok: np.ndarray
    inaccessible: np.ndarray
    target_visible: np.ndarray
    priority: np.ndarray
    edge_units: np.ndarray
    edge_heading: np.ndarray
    """``(V, k)`` heading of each edge's unit vector (:attr:`.grids.Grid.edge_unit_headings`)."""
    edge_angle: np.ndarray
    """``(V, k)`` heading of each edge's vector (:attr:`.grids.Grid.edge_headings`)."""
    wall_push: np.ndarray
    failures: np.ndarray


class LoopParameters(NamedTuple):
    """Scalars of a batch of ``R`` runs of ``n`` robots."""

    n: int
    situation: int
    policy: int
    repulsion: float
    communicates: bool
    exact: bool
    fixed_rotation: bool
    has_failures: bool
    record: bool
    rc2: float
    rso2: float
    cell: float
    reach2: float
    decision_seconds: float
    penalty: float
    step_seconds: float
    translate_seconds: float
    omega_max: float
    alpha_max: float
    turn_threshold: float
    """``omega_max² / alpha_max``: turns from this angle on reach the angular speed limit."""
    turn_cruise: float
    """``omega_max / alpha_max``."""
    turn_sigma: float
    n_vertices: int


class LoopState(NamedTuple):
    """What the steps change (in place); ``started`` and ``last_links_count`` are ``(1,)``."""

    pos: np.ndarray
    heading: np.ndarray
    alive: np.ndarray
    stopped: np.ndarray
    active: np.ndarray
    running: np.ndarray
    completed: np.ndarray
    steps: np.ndarray
    time: np.ndarray
    rounds: np.ndarray
    collisions: np.ndarray
    obstacle_collisions: np.ndarray
    visited: np.ndarray
    layers: np.ndarray
    targets: np.ndarray
    touched: np.ndarray
    dirty: np.ndarray
    unchecked: np.ndarray
    open: np.ndarray
    levy_heading: np.ndarray
    remaining: np.ndarray
    started: np.ndarray


class Relation(NamedTuple):
    """The sparse neighbour relation of :class:`~.neighbours.Neighbours` as arrays."""

    start: np.ndarray
    peer: np.ndarray
    link: np.ndarray
    sensed: np.ndarray
    owner: np.ndarray
    near: np.ndarray


@numba.njit(cache=True)
def relation(pts, n, alive, rc2, rso2, cell, reach2):
    """Neighbours of robots at ``pts (N, 2)`` in runs of ``n`` (:func:`.neighbours.find_neighbours`):
    ``start, peer`` (CSR), ``link`` (within ``r_c``, both alive), ``sensed`` (within ``r_so``,
    owner alive), ``owner`` and ``near`` (within ``r_c`` or ``r_so``) per entry."""
    start, peer, d2 = _pairs_within(pts, n, cell, reach2)
    L = len(peer)
    owner = np.empty(L, np.int64)
    link, sensed, near = np.empty(L, np.bool_), np.empty(L, np.bool_), np.empty(L, np.bool_)
    for i in range(len(pts)):
        for e in range(start[i], start[i + 1]):
            owner[e] = i
            in_rc, in_rso = d2[e] <= rc2, d2[e] <= rso2
            link[e] = in_rc and alive[i] and alive[peer[e]]
            sensed[e] = in_rso and alive[i]
            near[e] = in_rc or in_rso
    return start, peer, link, sensed, owner, near


@glue
def current_relation(t, p, s):
    """The relation at the robots' current vertices (empty for single robots)."""
    N = len(s.pos)
    if p.n > 1:
        pts = np.empty((N, 2))
        for i in range(N):
            pts[i, 0], pts[i, 1] = t.points[s.pos[i], 0], t.points[s.pos[i], 1]
        return relation(pts, p.n, s.alive, p.rc2, p.rso2, p.cell, p.reach2)
    none, empty = np.zeros(0, np.int64), np.zeros(0, np.bool_)
    return np.zeros(N + 1, np.int64), none, empty, empty, none, empty


@glue
def set_bits(s, layer, robot, vertex):
    """One bit of ``layer`` in ``robot``'s map (:func:`.knowledge.set_bit`)."""
    set_bit(s.layers, s.touched, s.dirty, s.unchecked, layer, robot, vertex)


@glue
def test_bit(s, layer, robot, vertex):
    """Whether ``robot``'s map holds ``vertex`` in ``layer``."""
    return (s.layers[robot, layer, vertex >> 6] >> np.uint64(vertex & 63)) & np.uint64(1) != 0


# -- observe: failures, steps 1-3, 7, 8 ---------------------------------------------------------
@glue
def fail_robots(t, p, s, step, events):
    """Failure injection: a robot whose failure step is reached stops for good."""
    for r in range(len(s.alive)):
        if t.failures[r] == step and s.alive[r]:
            if p.record:
                events.append((step, FAILURE, r, s.pos[r], 0, s.time[0]))
            s.alive[r] = False
    for r in range(len(s.alive)):
        s.active[r] = s.alive[r] and not s.stopped[r] and s.running[r // p.n]


@glue
def detect_failures(p, s, step, rel, events):
    """Step 3 failure information: live robots near a silent robot block its vertex (and,
    in situation 2, hold it visited); a watcher that did not know it records the event."""
    start, peer, link, sensed, owner, near = rel
    L = len(peer)
    seen = np.zeros(L, np.bool_)
    for e in range(L):
        seen[e] = near[e] and s.alive[owner[e]] and not s.alive[peer[e]]
    if p.record:
        known = np.zeros(L, np.bool_)
        for e in range(L):
            if seen[e]:
                known[e] = test_bit(s, 2, owner[e], s.pos[peer[e]])
        for e in range(L):
            if seen[e] and not known[e]:
                events.append((step, FAILURE_DETECTED, owner[e], peer[e], 0, s.time[0]))
    for e in range(L):
        if seen[e]:
            set_bits(s, 2, owner[e], s.pos[peer[e]])
            if p.situation == 2:
                set_bits(s, 0, owner[e], s.pos[peer[e]])


@glue
def exchange_maps(s, rel, last_links):
    """Step 3 map exchange over the links (:meth:`.knowledge.RobotMaps.exchange`); returns
    the links, the next exchange's ``last_links``."""
    start, peer, link, sensed, owner, near = rel
    count = 0
    for e in range(len(link)):
        count += link[e]
    receivers, senders = np.empty(count, np.int64), np.empty(count, np.int64)
    c = 0
    for e in range(len(link)):
        if link[e]:
            receivers[c], senders[c] = owner[e], peer[e]
            c += 1
    keys = receivers * len(s.layers) + senders
    fresh = _not_in_sorted(keys, last_links)
    if len(keys):
        _exchange(s.layers, s.touched, s.dirty, s.unchecked, receivers, senders, fresh, s.targets)
    else:
        s.dirty[:] = False
    return keys


@glue
def stop_received(p, s, own):
    """Step 8: the active robots that a stop broadcast by the robots ``own`` ends.

    Situation 1: rule (3) speaks of the targets, which every robot of the run knows
    alike, so the stop ends the search of every robot of the run (the paper's step 8).
    Situation 2: the stop carries the stopper's map, closed under travellable edges
    (rule (4)); it ends the search of a receiver whose vertex that map holds as sensed
    and not blocked: the receiver's whole accessible component is then visited. In a
    connected grid that is every robot (the paper's step 8); a robot trapped in a
    pocket, whose map covers only the pocket, no longer ends the others' search.
    """
    N, n = len(own), p.n
    heard = np.zeros(N, np.bool_)
    for r in range(N // n):
        for i in range(r * n, (r + 1) * n):
            if not s.active[i] or own[i]:
                continue
            for j in range(r * n, (r + 1) * n):
                if own[j] and (p.situation == 1 or (test_bit(s, 3, j, s.pos[i]) and not test_bit(s, 2, j, s.pos[i]))):
                    heard[i] = True
    return heard


@glue
def stop_robots(p, s, step, events):
    """Steps 7–8: rules (3)/(4) on each active robot's own map, the stop broadcasts, and the
    runs that end (every working robot stopped); updates ``active``."""
    N, n = len(s.pos), p.n
    if p.situation == 1:
        own = np.empty(N, np.bool_)
        for i in range(N):
            done = True
            for target in range(s.targets.shape[1]):
                done = done and s.targets[i, target]
            own[i] = done and s.active[i]
    else:
        own = _frontier_empty(s.layers, s.unchecked, s.open) & s.active
    if not own.any():
        return
    heard = stop_received(p, s, own)
    for r in range(N):
        if own[r] or heard[r]:
            if p.record:
                events.append((step, STOP, r, 1 if own[r] else 0, 0, s.time[0]))
            s.stopped[r] = True
    for run in range(N // n):
        any_stopped, all_done = False, True
        for i in range(run * n, (run + 1) * n):
            any_stopped |= s.stopped[i]
            all_done &= not (s.alive[i] and not s.stopped[i])
        if s.running[run] and any_stopped and all_done:
            s.completed[run] = True
            s.steps[run] = step
            s.running[run] = False
    for r in range(N):
        s.active[r] = s.alive[r] and not s.stopped[r] and s.running[r // n]


@glue
def observe(t, p, s, step, last_links, events):
    """Failures, steps 1–3 and the stop check of steps 7–8 at ``step``; returns the links
    for the next exchange and the neighbour relation for the next choice."""
    if p.has_failures:
        fail_robots(t, p, s, step, events)
    live = np.flatnonzero(s.active)
    rel = current_relation(t, p, s)
    if p.n > 1 and p.has_failures:
        detect_failures(p, s, step, rel, events)
    finder = sense_and_record(live, s.pos, p.n, s.visited, t.target_visible, s.targets, t.candidates, t.sensed_ok,
                              t.inaccessible, s.layers, s.touched, s.dirty, s.unchecked, p.situation == 2)
    if p.record:
        for target in range(len(finder)):
            if finder[target] >= 0:
                events.append((step, TARGET_FOUND, finder[target], target, 0, s.time[0]))
    if p.communicates and rel[2].any():
        last_links = exchange_maps(s, rel, last_links)
    stop_robots(p, s, step, events)
    return last_links, rel


# -- choose: steps 4-5 ----------------------------------------------------------------------------
@glue
def levy_flights(t, p, s, robots, u, z, flight):
    """LFP: robots whose flight is spent draw a new one (length from ``flight``, Mantegna's
    step length as numpy computed it; a turn of ``turn_sigma · z₂``, or a uniform heading
    for the first flight) and each takes one grid move (:func:`.step_kernels.levy_choices`)."""
    first = not s.started[0]
    s.started[0] = True
    for i in robots:
        if first or s.remaining[i] <= 0:
            s.remaining[i] = flight[i]
            if first:
                s.levy_heading[i] = 2 * np.pi * u[i]
            else:
                s.levy_heading[i] += p.turn_sigma * z[i, 2]
    return first


@glue
def choose(t, p, s, rel, u, z, flight):
    """Steps 4–5 of every active robot: ``(choice (N,), rounds per run (R,))``."""
    start, peer, link, sensed, owner, near = rel
    choice = s.pos.copy()
    R = len(s.running)
    if p.policy == SEQUENTIAL:
        aware = link | sensed
        rounds = sequential_choices(s.pos, s.active, t.priority, t.candidates, t.words, t.masks, t.sensed_ok, t.points,
                                    s.layers, s.touched, s.dirty, s.unchecked, start, peer, link, aware, u, p.repulsion > 0,
                                    p.n, choice)
        return choice, rounds
    robots = np.flatnonzero(s.active)
    if p.policy == RANDOM_UNVISITED:
        random_unvisited_choices(robots, s.pos, t.candidates, t.words, t.masks, t.sensed_ok, s.layers, s.touched, s.dirty,
                                 s.unchecked, u, choice)
        return choice, np.ones(R, np.int64)
    levy_flights(t, p, s, robots, u, z, flight)
    cos_h, sin_h = np.empty(len(robots)), np.empty(len(robots))
    for r in range(len(robots)):
        cos_h[r], sin_h[r] = math.cos(s.levy_heading[robots[r]]), math.sin(s.levy_heading[robots[r]])
    slot, slide = levy_choices(robots, s.pos, t.candidates, t.words, t.masks, t.sensed_ok, s.layers, start, peer, sensed,
                               sensed.any(), t.points, t.edge_units, t.wall_push, cos_h, sin_h, p.repulsion, s.remaining, choice)
    for r in range(len(robots)):
        if slide[r]:
            s.levy_heading[robots[r]] = t.edge_heading[s.pos[robots[r]], slot[r]]
    return choice, np.ones(R, np.int64)


# -- move: step 6 -----------------------------------------------------------------------------------
@glue
def bump_obstacles(t, p, s, step, choice, events):
    """Robots that take an edge blocked by an unsensed obstacle touch it and stay; they
    learn the vertex blocked; each touch is counted and recorded as an event."""
    N = len(choice)
    bumped = np.zeros(N, np.bool_)
    for i in range(N):
        if choice[i] != s.pos[i]:
            free = False
            for slot in range(t.neighbours.shape[1]):
                free |= t.edge_ok[s.pos[i], slot] and t.neighbours[s.pos[i], slot] == choice[i]
            bumped[i] = not free
    for i in range(N):
        if bumped[i]:
            s.obstacle_collisions[i // p.n] += 1
            if p.record:
                events.append((step, OBSTACLE_COLLISION, i, choice[i], 0, s.time[0]))
    for i in range(N):
        if bumped[i]:
            set_bits(s, 2, i, choice[i])
            choice[i] = s.pos[i]


@glue
def count_collisions(p, s, step, choice, events):
    """Collisions of the move per run (observer side), each recorded as an event."""
    R, n = len(s.running), p.n
    per_run = np.zeros(R, np.int64)
    if n > 1 and (n > SMALL_TEAM or may_collide(s.pos, choice, n)):
        run = np.arange(len(choice)) // n
        pairs = _collision_pairs(run * p.n_vertices + s.pos, run * p.n_vertices + choice, np.int64(n))
        for q in range(len(pairs)):
            r, i, j = pairs[q, 0], pairs[q, 1], pairs[q, 2]
            if s.running[r]:
                per_run[r] += 1
                if p.record:
                    events.append((step, COLLISION, i, j, choice[r * n + i], s.time[0]))
    for r in range(R):
        s.collisions[r] += per_run[r]
    return per_run


@glue
def heading_change(old, new):
    """Smallest absolute angle between two headings (:func:`.timing.heading_change`)."""
    return abs((new - old + np.pi) % (2 * np.pi) - np.pi)


@glue
def advance_turning_clocks(t, p, s, choice, rounds, per_run):
    """Trapezoidal rotation: each running run's clock advances by its choice rounds, its
    collision penalties and its slowest robot's turn and translation."""
    R, n = len(s.running), p.n
    dt = np.empty(R)
    for r in range(R):
        dt[r] = p.decision_seconds * rounds[r] + p.penalty * per_run[r]
    slowest = np.zeros(R)
    moving = False
    for i in range(len(choice)):
        if choice[i] != s.pos[i]:
            moving = True
            here = s.pos[i]
            new = 0.0
            for slot in range(t.neighbours.shape[1]):
                if t.neighbours[here, slot] == choice[i]:
                    new = t.edge_angle[here, slot]
            angle = heading_change(s.heading[i], new)
            if angle >= p.turn_threshold:
                turn = angle / p.omega_max + p.turn_cruise
            else:
                turn = 2.0 * math.sqrt(angle / p.alpha_max)
            slowest[i // n] = max(slowest[i // n], turn + p.translate_seconds)
            s.heading[i] = new
    for r in range(R):
        if moving:
            dt[r] = dt[r] + slowest[r]
        if s.running[r]:
            s.time[r] += dt[r]
            s.rounds[r] += rounds[r]


@glue
def move(t, p, s, step, choice, rounds, events):
    """Step 6: bump into unsensed obstacles, count collisions, advance the clocks, move."""
    if not p.exact:
        bump_obstacles(t, p, s, step, choice, events)
    per_run = count_collisions(p, s, step, choice, events)
    if p.fixed_rotation:
        advance_clocks(s.pos, choice, s.running, rounds, per_run, p.n, p.decision_seconds, p.penalty, p.step_seconds,
                       s.time, s.rounds)
    else:
        advance_turning_clocks(t, p, s, choice, rounds, per_run)
    s.pos[:] = choice


# -- the loop ---------------------------------------------------------------------------------------
@numba.njit(cache=True)
def event_rows(events):
    """The events as ``(m, 5)`` integers and ``(m,)`` clock times."""
    ints, times = np.empty((len(events), 5), np.int64), np.empty(len(events))
    for e in range(len(events)):
        step, kind, a, b, c, time = events[e]
        ints[e, 0], ints[e, 1], ints[e, 2], ints[e, 3], ints[e, 4] = step, kind, a, b, c
        times[e] = time
    return ints, times


@numba.njit(cache=True)
def run_steps(t, p, s, first, stop, last_links, u, z, flight, column):
    """Steps ``first … stop − 1`` (choose, move, observe of the next step) until every run
    has stopped, after :func:`observe` of step 0 when ``first`` is 0; ``u (N, m)``,
    ``z (N, m, 3)``, ``flight (N, m)`` hold the draws of steps ``first …`` in their
    columns from ``column`` on. Returns the steps taken, the links, the event rows, and
    the vertices ``(stop − first + 1, N)`` and run-0 clock after each step taken."""
    events = List.empty_list(EVENT)
    m = stop - first
    vertices = np.empty((m + 1 if p.record else 0, len(s.pos)), np.int64)
    clock = np.empty(m + 1 if p.record else 0)
    k = first
    observing = first == 0
    while True:
        if observing:
            last_links, rel = observe(t, p, s, k, last_links, events)
        else:
            rel = current_relation(t, p, s)
        if k >= stop or not s.running.any():
            break
        c = k - first
        choice, rounds = choose(t, p, s, rel, u[:, column + c], z[:, column + c], flight[:, column + c])
        move(t, p, s, k, choice, rounds, events)
        if p.record:
            vertices[c + 1] = s.pos
            clock[c + 1] = s.time[0]
        k += 1
        observing = True
    ints, times = event_rows(events)
    return k - first, last_links, ints, times, vertices, clock
