"""Discrete-step execution of a plan under disturbances (the label-flipping deadlock paper (2021), "Problem Statement").

Each step every robot chooses ``a_i(t)`` by RMTRACK (Eq. 1), possibly after the labels
changed: by flip tests (TFF/TFA, optionally guarded by the segment-graph cycle test), by
BTPG's first-come rule on the obstacles classified switchable offline (:mod:`.btpg`), or,
every few steps, by the ``optimal`` search over the open obstacles' labels
(:mod:`.optimal`); the disturbance
``δ_i(t) = 0`` with the probability of the region the robot stands in; then
``x_i(t + 1) = x_i(t) + a_i(t) δ_i(t)``. A run ends when every robot is finished, on a
deadlock (Definition 1: at least one robot waiting and none moving) or after
``max_steps``. Positions are checked for collisions (``‖p_i − p_j‖ < 2r``) every step.

Disturbances come from one random stream per ``(seed, robot, step)`` (drawn in blocks of
``DISTURBANCE_BLOCK`` steps per robot, keyed by ``(seed, robot, block)``), so every method
run with the same seed sees exactly the same disturbances: a paired comparison.

:class:`PlanExecutor` exposes the loop's pieces (``start``, ``decide``, ``move``,
``settle``, ``conclude``): :meth:`PlanExecutor.run` is their loop in memory, and
:func:`robofleet.coordination.simulation.simulate` drives the same pieces through the core
recorder.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..core.rng import keyed_generator
from .btpg import Classification, classify_switchable, first_come
from .coordination_space import CoordinationSpace
from .label_flipping import FlipContext, KnownProbabilities, LearnedProbabilities, flip_eligible, tfa_wants_flip, tff_wants_flip
from .optimal import OptimalOrders
from .options import DEFAULT_VISIT_BUDGET, Estimate, Method, OptimalSettings, Resolution
from .plain_steps import PlainStepRows, run_plain_steps, space_arrays
from .rmtrack import ActionRule
from .segment_graph import IncrementalCycleDetector, SegmentLayout, build_segment_layout, has_cycle_full
from .trajectories import Trajectories

DISTURBANCE_BLOCK = 256
DISTURBANCE_CACHE_BLOCKS = 128
"""Disturbance blocks kept per process (2 KB per robot each: 5 MB for 20 robots)."""


PAPER_METHODS = (Method.RMTRACK, Method.TFF, Method.TFA)
"""The methods of the label-flipping deadlock paper (Fig. 6), which take the deadlock check as an option."""
METHOD_NAMES = {Method.RMTRACK: "RMTRACK", Method.TFF: "RMTRACK+TFF", Method.TFA: "RMTRACK+TFA", Method.BTPG: "BTPG",
                Method.OPTIMAL: "optimal"}
FLIP_TESTS: dict[Method, Callable[[FlipContext], bool]] = {Method.TFF: tff_wants_flip, Method.TFA: tfa_wants_flip,
                                                           Method.BTPG: first_come}


@dataclass(frozen=True)
class Variant:
    """A method and whether its flips are guarded by the segment-graph cycle test.

    The check is an option of the paper's methods only: BTPG and ``optimal`` keep the
    segment graph acyclic by construction and ignore it (their name carries no suffix).
    """

    method: Method
    deadlock_check: bool

    @property
    def name(self) -> str:
        checked = self.deadlock_check and self.method in PAPER_METHODS
        return METHOD_NAMES[self.method] + (" (checked)" if checked else "")

    @property
    def flips_when_blocked(self) -> bool:
        """A robot stopped at an obstacle is offered a flip (TFF, TFA, BTPG)."""
        return self.method in (Method.TFF, Method.TFA, Method.BTPG)


ALL_VARIANTS = tuple(Variant(m, c) for m in PAPER_METHODS for c in (False, True))
"""The six variants of Fig. 6."""


class DisturbanceStream:
    """Uniform draws ``u_i(t)``, one stream per ``(seed, robot, step)``; robot disturbed iff ``u < p``."""

    def __init__(self, seed: int, n_robots: int):
        self.seed, self.n = int(seed), n_robots

    def uniforms(self, step: int) -> np.ndarray:
        """``u_i(step)`` ``(n,)``."""
        return self.block(step // DISTURBANCE_BLOCK)[step % DISTURBANCE_BLOCK]

    def block(self, block: int) -> np.ndarray:
        """The draws of steps ``block · B … (block + 1) · B − 1`` ``(B, n)``, ``B`` = :data:`DISTURBANCE_BLOCK`."""
        return disturbance_block(self.seed, self.n, block)


@functools.lru_cache(maxsize=DISTURBANCE_CACHE_BLOCKS)
def disturbance_block(seed: int, n_robots: int, block: int) -> np.ndarray:
    """Draws ``(B, n)`` of one block of steps, robot ``i``'s from the stream ``(seed, "disturbance", i, block)``.

    Cached per process (read-only): the six variants of a seed draw the same blocks.
    """
    draws = np.stack([keyed_generator(seed, "disturbance", robot, block).random(DISTURBANCE_BLOCK) for robot in range(n_robots)], axis=1)
    draws.flags.writeable = False
    return draws


@dataclass
class Execution:
    """What one execution recorded.

    ``progress`` ``(T + 1, n)``: ``x_i(t)``; ``waiting`` ``(T + 1, n)``: state at each step
    (the last row repeats the final state). ``decision_seconds``: wall time spent in flip
    tests, cycle checks and ``optimal`` decisions; ``stats``: every counter of the run
    (also ``decisions``, ``exhausted``, ``expansions`` of ``optimal``, ``offline_seconds``
    and ``switchable`` of BTPG).
    """

    progress: np.ndarray
    waiting: np.ndarray
    events: list[dict]
    labels: np.ndarray
    deadlock: bool
    finished: bool
    collisions: int
    flips: int
    refused_flips: int
    flip_tests: int
    decision_seconds: float
    arrival_steps: np.ndarray
    cycle_log: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        return int(len(self.progress) - 1)


@dataclass(frozen=True)
class Decision:
    """Eq. 1 at one step: the ``waiting``, ``moving`` and ``finished`` masks ``(n,)``."""

    waiting: np.ndarray
    moving: np.ndarray
    finished: np.ndarray

    @property
    def deadlocked(self) -> bool:
        """Definition 1: some robot waiting, none moving."""
        return bool(self.waiting.any() and not self.moving.any())

    @property
    def stop(self) -> bool:
        """The run ends here: every robot finished, or a deadlock."""
        return bool(self.finished.all()) or self.deadlocked


@dataclass
class ExecutionState:
    """What changes during one execution: progress ``x``, labels, flip bookkeeping, statistics."""

    x: np.ndarray
    labels: np.ndarray
    tried: np.ndarray
    detector: IncrementalCycleDetector | None
    stream: DisturbanceStream
    rule: ActionRule
    arrival: np.ndarray
    events: list[dict]
    stats: dict = field(default_factory=lambda: {"flips": 0, "refused": 0, "tests": 0, "seconds": 0.0, "collisions": 0,
                                                 "decisions": 0, "exhausted": 0, "expansions": 0, "offline_seconds": 0.0,
                                                 "switchable": 0})
    deadlock: bool = False
    cycle_log: list = field(default_factory=list)
    orders: OptimalOrders | None = None


@dataclass
class PlanExecutor:
    """Runs one variant on one plan.

    Parameters
    ----------
    traj, space:
        the plan and its coordination space.
    variant:
        method and whether flips are guarded by the segment-graph cycle test.
    times:
        expected-time model for the flip tests (known or learned probabilities).
    probability:
        ``(n, K_max + 1)`` true disturbance probability at each plan step.
    layout:
        segment layout (built on demand when the check is on).
    flip_test:
        override of the flip test (tests use it to inject arbitrary flips).
    detector:
        the cycle-test class (``IncrementalCycleDetector``; tests and benchmarks pass
        a subclass that checks or times each answer against the full reference).
    disturbed:
        override ``disturbed(step, progress) -> bool (n,)`` of the random disturbances.
    observe_cells:
        ``(n, K_max + 1)`` map cells for a learned estimate.
    record_cycles:
        record at every step whether the active segment graph has a cycle (tests).
    compiled:
        run the plain steps in compiled code (:mod:`.plain_steps`; the same trace);
        ``False`` runs every step through the numpy code (tests compare the two).
    optimal:
        horizon, node budget and decision period of ``method: optimal``.
    btpg_budget:
        vertices BTPG's offline classification may visit (:func:`.btpg.classify_switchable`).
    """

    traj: Trajectories
    space: CoordinationSpace
    variant: Variant
    times: KnownProbabilities | LearnedProbabilities
    probability: np.ndarray
    layout: SegmentLayout | None = None
    resolution: Resolution = Resolution.EXACT
    flip_test: Callable[[FlipContext], bool] | None = None
    detector: type[IncrementalCycleDetector] = IncrementalCycleDetector
    disturbed: Callable[[int, np.ndarray], np.ndarray] | None = None
    observe_cells: np.ndarray | None = None
    record_cycles: bool = False
    compiled: bool = True
    optimal: OptimalSettings = OptimalSettings()
    btpg_budget: int = DEFAULT_VISIT_BUDGET

    def run(self, seed: int, max_steps: int) -> Execution:
        """Execute until all robots finish, a deadlock or ``max_steps``.

        The loop of :meth:`start`, :meth:`decide` and :meth:`move`, collecting the rows in
        memory; :func:`robofleet.coordination.simulation.simulate` drives the same steps
        through the core recorder instead.
        """
        state = self.start(seed)
        decision, t = (self.decide(state, 0) if max_steps > 0 else self.settle(state)), 0
        rows_x, rows_wait = [state.x[None].copy()], [decision.waiting[None]]
        scratch = PlainStepRows.empty(DISTURBANCE_BLOCK, self.traj.n_robots)
        while not decision.stop and t < max_steps:
            done, decision = self.plain_steps(state, decision, t, max_steps, scratch)
            if done > t:
                rows_x.append(scratch.progress[: done - t].copy())
                rows_wait.append(scratch.waiting[: done - t].copy())
                t = done
                continue
            self.move(state, decision, t)
            t += 1
            decision = self.decide(state, t) if t < max_steps else self.settle(state)
            rows_x.append(state.x[None].copy())
            rows_wait.append(decision.waiting[None])
        self.conclude(state, t)
        return self.execution(state, np.concatenate(rows_x), np.concatenate(rows_wait))

    def start(self, seed: int, events: list[dict] | None = None) -> ExecutionState:
        """The state at ``t = 0``: plan labels, everybody at step 0; ``events`` collects the run's events."""
        n = self.traj.n_robots
        labels = self.space.initial_labels.copy()
        tried = np.zeros(self.space.n_obstacles, dtype=bool)
        state = ExecutionState(
            x=np.zeros(n, dtype=np.intp), labels=labels, tried=tried,
            detector=self._detector(labels), stream=DisturbanceStream(seed, n), rule=ActionRule(self.space),
            arrival=np.where(self.traj.lengths == 0, 0, -1), events=[] if events is None else events,
        )
        if self.variant.method is Method.BTPG:  # fixed obstacles are never offered: they count as settled
            classification = self.btpg_classification
            tried |= ~classification.switchable
            state.stats["offline_seconds"] = classification.seconds
            state.stats["switchable"] = classification.n_switchable
        elif self.variant.method is Method.OPTIMAL:
            state.orders = OptimalOrders(self.space, self.exact_layout, self.optimal, self.traj.dt)
        return state

    def decide(self, state: ExecutionState, t: int) -> Decision:
        """Step ``t``'s decisions: flip tests (TFF/TFA), first come (BTPG) or the optimal orders
        (every ``optimal.period`` steps, and when a robot stopped where the order may change
        calls one), then Eq. 1; flags a deadlock (Definition 1)."""
        blocking = state.rule.blocking_sides(state.labels, state.x)
        flips = state.stats["flips"]  # every relabelling counts one: unchanged, the labels keep ``blocking``
        if self.variant.flips_when_blocked:
            self._flip_round(state.labels, state.x, state.tried, state.detector, state.stats, state.events, t, blocking)
        elif state.orders is not None:
            called = state.orders.call(blocking, state.x, state.tried)
            if called or state.orders.due(t):
                self._optimal_round(state, t)
        waiting, moving, finished = state.rule.states(state.labels, state.x,
                                                      blocking if state.stats["flips"] == flips else None)
        if self.record_cycles:
            state.cycle_log.append(self._cycle_now(state.labels, state.x))
        decision = Decision(waiting, moving, finished)
        if decision.deadlocked:
            state.deadlock = True
            state.events.append({"step": t, "kind": "deadlock", "robots": np.flatnonzero(waiting).tolist()})
        return decision

    def plain_steps(self, state: ExecutionState, decision: Decision, k: int, max_steps: int, rows: PlainStepRows) -> tuple[int, Decision]:
        """Execute the plain steps from ``k`` on in compiled code (:mod:`.plain_steps`), at most
        to the end of ``k``'s disturbance block, writing their rows into ``rows``.

        Returns the first step not executed (``k`` when step ``k`` is not plain, or when the
        compiled path is off) and the decision of that step.
        """
        if not self.compiles:
            return k, decision
        block = k // DISTURBANCE_BLOCK
        stop = (block + 1) * DISTURBANCE_BLOCK
        quiet = state.tried
        if state.orders is not None:  # the next periodic decision, and a robot stopped where it calls one, run through ``decide``
            stop = min(stop, state.orders.next_decision(k) - 1)
            quiet = state.orders.quiet(state.tried)
        moving, waiting = decision.moving.copy(), decision.waiting.copy()
        done = run_plain_steps(
            k, stop, max_steps, state.stream.block(block), block * DISTURBANCE_BLOCK, state.x, moving,
            waiting, state.labels, quiet, self.variant.method is not Method.RMTRACK, self.probability, self.traj.positions,
            self.traj.lengths, (2 * self.traj.radius) ** 2, self.side_arrays, rows.disturbed, rows.progress, rows.waiting,
        )
        if done == k:
            return k, decision
        return done, Decision(waiting, moving, state.x >= self.space.lengths)

    @property
    def compiles(self) -> bool:
        """Whether :meth:`plain_steps` runs (not with overridden disturbances, a learned estimate or cycle recording)."""
        return self.compiled and self.disturbed is None and self.observe_cells is None and not self.record_cycles

    @functools.cached_property
    def side_arrays(self) -> tuple[np.ndarray, ...]:
        return space_arrays(self.space)

    @functools.cached_property
    def exact_layout(self) -> SegmentLayout:
        """The segment layout with the exact resolution (BTPG and ``optimal`` reason on it)."""
        if self.layout is not None and self.layout.resolution is Resolution.EXACT:
            return self.layout
        return build_segment_layout(self.space, Resolution.EXACT)

    @functools.cached_property
    def btpg_classification(self) -> Classification:
        """BTPG's offline classification of the plan's obstacles (computed once per executor)."""
        return classify_switchable(self.space, self.exact_layout, self.btpg_budget)

    def settle(self, state: ExecutionState) -> Decision:
        """Eq. 1 at the end of the step budget, without flip tests (the state the run ends in)."""
        return Decision(*state.rule.states(state.labels, state.x))

    def move(self, state: ExecutionState, decision: Decision, t: int) -> np.ndarray:
        """``x(t + 1) = x(t) + a(t) δ(t)``, arrivals and collisions; returns the disturbed mask ``(n,)``."""
        state.x, hit = self._advance(state.x, decision.moving, t, state.stream)
        newly = (state.arrival < 0) & (state.x >= self.traj.lengths)
        state.arrival[newly] = t + 1
        state.stats["collisions"] += self._collisions(state.x, t + 1, state.events)
        return hit

    def conclude(self, state: ExecutionState, n_steps: int) -> None:
        """Record a ``timeout`` event when the budget of ``n_steps`` steps ended the run."""
        if not np.all(state.x >= self.traj.lengths) and not state.deadlock:
            state.events.append({"step": n_steps, "kind": "timeout"})

    def execution(self, state: ExecutionState, progress: np.ndarray, waiting: np.ndarray) -> Execution:
        """The run as an :class:`Execution` from its final state and its rows."""
        stats = state.stats
        return Execution(
            progress=progress, waiting=waiting, events=state.events, labels=state.labels,
            deadlock=state.deadlock, finished=bool(np.all(state.x >= self.traj.lengths)), collisions=stats["collisions"],
            flips=stats["flips"], refused_flips=stats["refused"], flip_tests=stats["tests"],
            decision_seconds=stats["seconds"], arrival_steps=state.arrival, cycle_log=state.cycle_log, stats=dict(stats),
        )

    def _detector(self, labels: np.ndarray) -> IncrementalCycleDetector | None:
        if not self.variant.deadlock_check or self.variant.method not in (Method.TFF, Method.TFA):
            return None
        if self.layout is None:
            self.layout = build_segment_layout(self.space, self.resolution)
        return self.detector(self.layout, labels)

    def _flip_round(self, labels, x, tried, detector, stats, events, t, blocking) -> None:
        """Flip tests for every waiting robot's blocking obstacles (in robot order); ``blocking``:
        the rule's :meth:`~.rmtrack.ActionRule.blocking_sides` of ``labels`` and ``x``."""
        blocking = np.flatnonzero(blocking)
        if len(blocking) == 0:
            return
        test = self.flip_test or FLIP_TESTS[self.variant.method]
        for side in blocking[np.argsort(self.space.side_waiter[blocking], kind="stable")].tolist():
            if not flip_eligible(self.space, side, x, tried):
                continue
            obstacle, w, a = side // 2, int(self.space.side_waiter[side]), int(self.space.side_other[side])
            if labels[obstacle] != a:
                continue
            tried[obstacle] = True
            t0 = time.perf_counter()
            stats["tests"] += 1
            wanted = test(FlipContext(self.space, side, w, a, x, self.times, labels))
            accepted = wanted and (detector is None or detector.try_flip(obstacle, w, x))
            stats["seconds"] += time.perf_counter() - t0
            if accepted:
                labels[obstacle] = w
                stats["flips"] += 1
                events.append({"step": t, "kind": "flip", "robot": w, "other": a, "obstacle": obstacle})
            elif wanted:
                stats["refused"] += 1
                events.append({"step": t, "kind": "flip_refused", "robot": w, "other": a, "obstacle": obstacle})

    def _optimal_round(self, state: ExecutionState, t: int) -> None:
        """The ``optimal`` decision at step ``t``: relabel the open obstacles as the search chose
        (obstacles in ``tried`` stay closed: the supervisor marks those whose label robot may
        already have reached them)."""
        t0 = time.perf_counter()
        probability = self.times.probability if isinstance(self.times, KnownProbabilities) else self._learned_probability()
        solution = state.orders.decide(state.labels, state.x, state.tried, t, probability, state.arrival)
        stats = state.stats
        if solution is not None:
            stats["decisions"] += 1
            stats["exhausted"] += int(solution.exhausted)
            stats["refused"] += int(solution.reverted)
            stats["expansions"] += solution.expansions
            for o in np.flatnonzero(solution.labels != state.labels).tolist():
                w, a = int(solution.labels[o]), int(state.labels[o])
                stats["flips"] += 1
                state.events.append({"step": t, "kind": "flip", "robot": w, "other": a, "obstacle": o})
            state.labels[:] = solution.labels
        stats["seconds"] += time.perf_counter() - t0

    def _learned_probability(self) -> np.ndarray:
        """``(n, K_max + 1)`` the learned estimate at every plan step."""
        width = self.traj.positions.shape[1]
        return np.stack([self.times.probabilities(r, 0, width) for r in range(self.traj.n_robots)])

    def _advance(self, x, moving, t, stream) -> tuple[np.ndarray, np.ndarray]:
        """``x(t + 1) = x(t) + a(t) δ(t)``; also returns which robots were disturbed."""
        if self.disturbed is not None:
            hit = np.asarray(self.disturbed(t, x), dtype=bool)
        else:
            p = self.probability[np.arange(len(x)), x]
            hit = stream.uniforms(t) < p
        if self.observe_cells is not None:
            self.times.observe(self.observe_cells[np.arange(len(x)), x], moving, hit)
        return x + (moving & ~hit), hit

    def _collisions(self, x, step, events) -> int:
        pos = self.traj.at(x)
        d2 = ((pos[:, None] - pos[None]) ** 2).sum(-1)
        i, j = np.nonzero(np.triu(d2 < (2 * self.traj.radius) ** 2, k=1))
        for a, b in zip(i.tolist(), j.tolist()):
            events.append({"step": step, "kind": "collision", "robots": [a, b]})
        return len(i)

    def _cycle_now(self, labels, x) -> bool:
        if self.layout is None:
            self.layout = build_segment_layout(self.space, self.resolution)
        return has_cycle_full(self.layout, labels, x)
