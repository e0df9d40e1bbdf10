"""An online RMTRACK supervisor (the label-flipping deadlock paper (2021), Eq. 1; Čáp,
Gregoire & Frazzoli 2016), fed what the robots report, in any order and at any rate.

Use
    ``sup = Supervisor.from_csv("plan.csv", radius=…, dt=…, method="tff")`` (or
    ``Supervisor(trajectories)``, or :meth:`Supervisor.from_scenario`); then, whenever a
    robot reports, ``sup.report(i, progress=k)`` or ``sup.report(i, position=(x, y))``, and
    ``sup.answer(i)`` tells it ``go`` (with the plan step ``until`` it may advance to) or
    ``wait`` (or ``done``). Reports only update what the supervisor knows; answers are
    computed from that knowledge, so they depend on which reports have arrived, never
    on the order in which they did. Any thread may call any method (see *Threads*).

What it knows
    For every robot a lower bound of its true progress, ``known`` (the plan step it has
    certainly reached: the largest step it has reported, or what its positions prove,
    below), and an upper bound, ``reach`` (the furthest step it may have reached: the
    ``until`` of its answers, unless it has since reported that it holds still —
    ``holding=True``: it stays at the reported step until it receives an answer given
    after that report; a robot of a discrete-step simulation holds between steps). An
    older report arriving late changes nothing: ``known`` only grows. And the furthest
    step its latest report lets it stand at, ``standing`` (its known step after a
    progress report).

Position reports
    A robot with true progress ``t`` (the last plan step it has reached) stands at
    ``π(t)`` or, moving on, on the segment from ``π(t)`` to ``π(t + 1)``; holding still it
    stands at ``π(t)``. A reported position ``p`` is *consistent* with a step ``s`` of the
    robot's window ``known ≤ s ≤ reach`` when ``p`` lies within ``position_tolerance`` of
    where a robot at progress ``s`` can stand (the point ``π(s)`` for a holding report or
    ``s = reach``, else the segment ``π(s) → π(s + 1)``). The report credits the robot the
    *smallest* consistent step, and a holding report sets ``reach`` to the *largest*.

    Condition: the reported position lies within ``position_tolerance`` of where the
    robot is when the report is recorded (the tolerance covers the sensing error and
    the distance the robot may travel while its report is in transit; progress reports
    need no such condition).

    Claim: then ``known ≤ t ≤ reach`` at every moment, for any plan (one that passes the
    same point twice, backs up or waits) and any error within the tolerance. Proof, by
    induction over events. Initially all three are 0. A robot moves only up to the
    ``until`` of an answer, and every ``until`` given is counted in ``reach`` (a robot
    that has reported holding moves only on answers given after that report, whose
    ``until`` are counted again), so ``t ≤ reach`` holds as the robot moves; answers
    only raise ``reach``. A progress report ``k`` is a step the robot has reached
    (``k ≤ t``; a holding one is its current step, ``k = t``), and ``known`` becomes
    ``max(known, k) ≤ t``. A position report: by the induction hypothesis ``t`` lies in the
    window, and by the condition the report is consistent with ``t``, so the smallest
    consistent step is ``≤ t`` and, for a holding report, the largest is ``≥ t``.
    Distances are compared with a margin of a few rounding errors (:data:`ROUNDING`),
    which only widens the consistent set. ∎ Since every decision below reads ``known``
    as the robots' progress and ``reach`` as how far they may be, the guarantees need
    nothing else from the positions.

    What it costs: a step that cannot be told apart from an earlier one is not
    credited, and the robots that wait for it wait longer. A moving robot's report never
    credits the step it stands on (it could be just short of it): a robot that stops
    says so (``holding=True``), at its goal too. A holding robot at step ``u`` is
    credited ``u`` once a report of it lands farther than the tolerance from ``π(s)``
    for every window step ``s < u``; with errors that vary from report to report this
    happens unless its plan stood at a point within ``2 · position_tolerance`` of
    ``π(u)`` earlier within the window (a wait, short steps, a revisit), and otherwise
    as soon as the robot has moved on. So that an ambiguous report never leaves a robot
    standing past its grant, an answer grants at least one step past the furthest step
    the robot's latest report lets it stand at (see ``until`` below): a robot that is not
    held back by Eq. 1 always moves on.

The decisions (one code path with the simulation)
    An answer runs, on the known progress, exactly the decision step of the family's
    :class:`~.plan_execution.PlanExecutor` (``decide``: the flip round of RMTRACK+TFF /
    RMTRACK+TFA for the robots Eq. 1 stops, each flip kept only if the segment graph stays
    acyclic with the incremental Pearce–Kelly test, then Eq. 1 for every robot). Two
    additions make it safe with information that is late:

    * Eq. 1 and the cycle test use the known (lower-bound) progress. Eq. 1 only waits
      more when another robot's progress is underestimated (``top(x_i + 1) ≥ x_j`` holds
      for a smaller ``x_j``), and the active subgraph only grows, so the answers are never
      less safe than with exact information — only later.
    * A flip of obstacle ``o`` to the waiting robot is tried only while the other robot
      *cannot* have reached ``o``: its furthest possible step (above) is below its first
      step in ``o``. (The simulation's condition, ``x_a < B_a``, for a robot that may have
      moved since it reported.)

    ``until`` is the last step before the first column where Eq. 1 would stop the robot,
    given what is known now, and at most ``lookahead`` steps ahead — or one step past the
    furthest step its latest report lets it stand at, if that is further (a position
    report that several steps fit): advancing column by column there keeps Eq. 1's
    invariant (every column ``≤ x_i`` of an obstacle labelled ``j`` lies below ``x_j``),
    since the others' progress only grows; a flip never moves it back (flips need the
    other robot to be before the obstacle).

Threads
    Every public method holds the supervisor's (re-entrant) lock while it runs, so calls
    from several threads take effect one at a time, as if made in some order by one
    thread: a decision is computed from the knowledge of one instant and cached only
    until the next report that changes that knowledge (no report can slip in between
    computing a decision and caching it, which would keep an outdated decision, and
    robots waiting on it, for good), and two decisions never run on the shared flip
    state at once.

Lifelong plans
    :meth:`Supervisor.append_plan` gives a robot known at its goal further plan steps;
    :meth:`Supervisor.cut_plan` ends a robot's plan at a step it may not yet have passed
    (not below its furthest possible step ``reach``), where it then parks for good. Step
    numbers never change (the plans keep their history), so ``known ≤ t ≤ reach`` carries
    over. The coordination space is rebuilt and the labels are carried over: a region
    with the same cells as before keeps its label, a part of a region (a cut) keeps that
    region's label, and every other region (new cells of an appended plan, alone or joined
    to old ones) starts with the other robot first: the appended robot yields. Then the
    change *settles* the regions of the changed robot that it changed or in which the
    robot passing first parks (its waiter would wait for ever), one at a time: each keeps
    its label if that order is *admissible*, else goes to the other robot if that one is,
    else the change is refused with a one-line error giving both reasons, and nothing
    changes. A robot ``ℓ`` passing first in region ``o`` with waiter ``w`` is admissible
    when (a) ``ℓ`` does not park inside ``o``; (b) every column of ``w`` up to its furthest
    possible step ``reach_w`` lies below ``ℓ``'s known step (Eq. 1's invariant holds
    already); (c) a flip: the flip keeps the active segment graph acyclic — the
    incremental cycle test of :mod:`.segment_graph`, exact resolution, on the known
    progress, whatever the method and whether its deadlock check is on. One reordering
    before a refusal: when the appended robot ``w`` must pass first in a region (the other
    robot parks there) and only (c) fails, ``w`` passes first also in the regions it was
    to yield in and enters before clearing that one, earliest first, each flip made only
    when admissible, until the region's flip passes (c); if it never does, the change is
    refused.

    Claim 1 (no collision): the change keeps Eq. 1's invariant (every column ``≤ x_w`` of
    a region whose label is the other robot ``a`` lies below ``x_a``) for the true
    progress. Proof. A kept region: unchanged. A region not settled that is part of a
    region (a cut): its columns and rows are those of the region, its profiles no higher.
    A settled region: by (b), since ``x_w ≤ reach_w`` and ``known_ℓ ≤ x_ℓ``; the label
    robot's own side is inactive. ∎ The collision guarantee below then holds after any
    sequence of changes, by the same induction.

    Claim 2 (no cycle): the active segment graph (vertices not entered at the known
    progress) stays acyclic through a change, for every method. Proof. Before the change
    it is acyclic (induction; Guarantees below). The carried labels: a kept region keeps
    its edges; a part of a region keeps edges from the same or an earlier vertex of the
    same robot, so a cycle through one would give a cycle through the old edge (follow
    the robot's path from the earlier vertex to the old one); a region the appended robot
    ``w`` yields in adds edges into ``w``'s columns only, and those not entered are new
    segments (``w`` is known at its old goal), whose only outgoing edges are ``w``'s own
    path: the edges of a kept region whose label is ``w`` leave from ``w``'s step
    ``top + 1`` after its highest cell, at most its old goal, since ``w`` parks in no
    region it passes first (Claim 3 before the change) — a vertex ``w`` has entered. So
    no cycle passes through them.
    The segment graph is built on these labels and the change is refused if it has a
    cycle anyway. Then every relabelling the change makes, reorderings included, is a
    flip kept only by (c). ∎
    Without (c) a change can close a cycle: robot ``w`` appended past the goal of a robot
    ``p`` that is still on its way must go first there, and if ``p`` passes first in a
    region with a robot ``b`` after entering ``w``'s region, while ``w`` yields to ``b``
    before clearing it, the three wait for each other for ever (the seeded closed loops of
    the tests find such changes within a few runs). The reordering then lets ``w`` pass
    first where it met ``b`` too, if ``b`` cannot be there yet.

    Claim 3 (nobody waits for a parked robot): after a change, no active region's robot
    passing first parks inside it. Proof: the regions of the changed robot in which one
    would are settled, a settled region's label never parks (a), regions of other robots
    keep their plans and labels, and no later flip gives a region to a robot that parks
    in it (:func:`~.label_flipping.flip_eligible`; BTPG and ``optimal`` keep such regions
    fixed). ∎ With Claims 2 and 3, Theorems 1–2 apply to the new plan: the deadlock
    guarantee below carries over. A robot with an appended plan is told ``go`` again by
    its next answer.

    After a change, the method's own flips are checked against the new plan's segment
    graph too: TFF and TFA with the deadlock check, BTPG (its offline classification holds
    for the plan it was made on, so every later first-come flip goes through the cycle
    test) and ``optimal`` (its decisions restart on the new plan with this cycle test).

    Costs and limits: rebuilding is that of the whole plan's coordination space (distances
    for the pairs with the changed robot only: the other pairs' cells carry over) and its
    segment graph, plus a dense ``K_i × K_j`` grid for each pair with the changed robot;
    appends need known disturbance probabilities (the new steps take the goal's); an
    appended path that ends on another robot's remaining path, or passes a robot parked
    at its goal, is refused, and so is any change whose regions have no admissible order
    (a caller may then try another path or another step).

Guarantees
    With a collision-free plan, robots that never pass their latest ``until`` and
    positions within the tolerance (above): no collision in the coordination space (Eq.
    1's invariant), and, for RMTRACK (no flips), TFF and TFA with the deadlock check on,
    BTPG and ``optimal`` (by construction), the active segment graph stays acyclic —
    every flip kept and every plan change (*Lifelong plans*) leaves it so — hence no
    deadlock (Theorems 1–2 with the exact resolution). As soon as every
    robot's latest report has arrived, the answers are those of the simulation in the
    same state (the tests replay recorded simulations through it with reports late, out
    of order and missing for a while). A robot that stops reporting can only make others
    wait for it.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np
from scipy import ndimage

from ..core import arguments
from ..core.config import ScenarioSource, load_spec
from ..core.errors import ConfigError, InfeasibleError, short_repr
from ..core.geometry import point_segment_distance
from ..core.rng import resolve_seed
from .coordination_space import CoordinationSpace, build_coordination_space, pair_cells, space_of_cells
from .instance import prepare_instance
from .label_flipping import KnownProbabilities
from .plan_execution import Decision, ExecutionState, Method, PlanExecutor, Variant
from .rmtrack import ActionRule
from .optimal import OptimalOrders
from .segment_graph import IncrementalCycleDetector, Resolution, build_segment_layout
from .simulation import make_executor
from .spec import Spec
from .trajectories import Trajectories, load_trajectories

DEFAULT_LOOKAHEAD = 10
"""Plan steps granted past a robot's known progress at most (1 s at the paper's Δ = 100 ms)."""

ROUNDING = 1e-9
"""Relative margin on the distances of a position report (see *Position reports*): a
position exactly at the tolerance is never refused for a rounding error."""

SCAN_ROWS = 32
"""Profile entries in a robot's window up to which :meth:`Supervisor.horizon` scans them in
plain Python (cheaper than numpy's per-call overhead on a few entries); more go through
numpy. Both give the same step."""

Result = TypeVar("Result")


def locked(method: Callable[..., Result]) -> Callable[..., Result]:
    """Run ``method`` holding its supervisor's lock (see *Threads* in the module docstring)."""

    @functools.wraps(method)
    def run_locked(self: Supervisor, *args, **kwargs) -> Result:
        with self._lock:
            return method(self, *args, **kwargs)

    return run_locked


@dataclass(frozen=True)
class Answer:
    """What a robot is told.

    Attributes
    ----------
    robot : int
        Its index.
    action : str
        ``"go"``, ``"wait"`` or ``"done"`` (at its goal).
    until : int
        The plan step it may advance to (its known progress when waiting or done).
    progress : int
        The step the supervisor knows it at.
    stop_at : numpy.ndarray
        ``(2,)`` the planned position of step ``until``: where it must stop unless told otherwise.
    """

    robot: int
    action: str
    until: int
    progress: int
    stop_at: np.ndarray

    @property
    def go(self) -> bool:
        return self.action == "go"


class Supervisor:
    """Online RMTRACK (+TFF/TFA, + the segment-graph check; or BTPG, ``optimal``) over a
    plan that may grow and shrink (:meth:`append_plan`, :meth:`cut_plan`).

    Parameters
    ----------
    trajectories: the plan.
    method: ``"rmtrack"``, ``"tff"``, ``"tfa"``, ``"btpg"`` or ``"optimal"``.
    deadlock_check: refuse flips that close a cycle in the segment graph.
    probability: disturbance probability used by the flip tests' expected times, one
        number or ``(n, K_max + 1)`` per robot and plan step, in ``[0, 1)``.
    resolution: segment-graph resolution (``"exact"`` or ``"definition3"``).
    position_tolerance: largest distance of a reported position from where the robot is
        when the report is recorded, a number ``≥ 0`` (default: the robot radius). Known
        progress stays a lower bound of the true progress as long as reports keep to it
        (see *Position reports* in the module docstring).
    lookahead: at most this many plan steps past its known progress are granted to a
        robot at once (``None``: up to the first column Eq. 1 would stop it). A robot
        that reports less often than every ``lookahead`` steps stops and waits for its
        next answer; a longer look-ahead leaves fewer flips possible, since a flip needs
        the other robot not yet permitted into the obstacle.
    executor: a ready :class:`~.plan_execution.PlanExecutor` on the same plan (used by
        :meth:`from_scenario`; ``method``, ``deadlock_check``, ``probability`` and
        ``resolution`` are then ignored).

    Every public method may be called from any thread: each holds the supervisor's lock
    while it runs (see *Threads* in the module docstring).
    """

    def __init__(self, trajectories: Trajectories, *, method: str = "rmtrack", deadlock_check: bool = True,
                 probability: float | np.ndarray = 0.05, resolution: str = "exact", position_tolerance: float | None = None,
                 lookahead: int | None = DEFAULT_LOOKAHEAD, executor: PlanExecutor | None = None):
        if executor is None:
            executor = plan_executor(trajectories, method, deadlock_check, probability, resolution)
        self.executor = arguments.instance(executor, PlanExecutor, "executor", "a PlanExecutor or None")
        self.traj, self.space = self.executor.traj, self.executor.space
        self.execution_state: ExecutionState = self.executor.start(0)
        n = self.traj.n_robots
        self.known = np.zeros(n, np.intp)
        self.reach = np.zeros(n, np.intp)
        self.rounds = 0
        self._decision: Decision | None = None
        self._lock = threading.RLock()
        self.tolerance = self.traj.radius if position_tolerance is None else tolerance_value(position_tolerance)
        self.lookahead = arguments.count(lookahead, "lookahead", minimum=1, optional=True)
        self._entries = ProfileEntries.of(self.space)
        self._first_sides = 2 * np.arange(self.space.n_obstacles)
        self.standing = np.zeros(n, np.intp)
        self._cells: dict[tuple[int, int], np.ndarray] | None = None

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def from_csv(cls, path: str | Path, *, radius: float, dt: float, **options) -> Supervisor:
        """From a user's plan file (``robot,step,x,y`` CSV, or NPZ; see :func:`~.trajectories.load_trajectories`)."""
        return cls(load_trajectories(path, radius, dt), **options)

    @classmethod
    def from_scenario(cls, spec: ScenarioSource, seed: int = 0, **options) -> Supervisor:
        """The plan, flip policy and disturbance probabilities a coordination scenario's run
        ``seed`` executes (the same instance and executor as ``simulate(spec, seed)``).
        ``spec``: a shipped name, a YAML file, a mapping or a validated spec
        (:func:`~robofleet.core.config.load_spec`)."""
        spec = load_spec(spec, Spec, argument="spec")
        seed = resolve_seed(seed)
        workspace = spec.build_workspace()
        instance = prepare_instance(spec, seed, workspace)
        variant = Variant(spec.policy.method, spec.policy.deadlock_check)
        return cls(instance.trajectories, executor=make_executor(spec, instance, workspace, variant), **options)

    # -- what the robots say --------------------------------------------------------------------
    @locked
    def report(self, robot: int, *, progress: int | None = None, position: object = None, holding: bool = False) -> int:
        """Record a robot's report: its plan step ``progress`` or its ``position``.

        A report older than what is known (a smaller step) changes nothing. ``holding``:
        the robot holds still at this step until it receives an answer given after this
        report (answers given before it no longer count). A position credits the smallest
        plan step it is consistent with, which is never past the robot's true progress
        when the position lies within ``position_tolerance`` of where the robot is (see
        *Position reports* in the module docstring). Returns the step now known for the
        robot.
        """
        i = self.robot_index(robot)
        holding = holding if type(holding) is bool else arguments.flag(holding, "holding")
        if (progress is None) == (position is None):
            raise ConfigError(f"report: expected exactly one of progress= or position=, received progress={progress!r}, position={short_repr(position)}")
        if progress is not None:
            lowest = highest = self.checked_step(i, progress)
        else:
            lowest, highest = self.steps_of_position(i, position, holding)
        known, reached = int(self.known[i]), int(self.reach[i])
        if lowest > known:
            self.known[i] = known = lowest
            self._decision = None
        self.standing[i] = max(known, highest)
        reach = max(known, highest) if holding else max(reached, known)
        if reach < reached:  # a robot known to hold still may be offered flips again
            self._decision = None
        self.reach[i] = reach
        return known

    def robot_index(self, robot: object) -> int:
        n = len(self.known)
        if type(robot) is int and 0 <= robot < n:  # the common case first
            return robot
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 0 <= robot < n:
            raise ConfigError(f"robot: expected an index in 0..{n - 1}, received {short_repr(robot)}")
        return int(robot)

    def checked_step(self, i: int, progress: object) -> int:
        k = int(self.traj.lengths[i])
        if type(progress) is int and 0 <= progress <= k:  # the common case first
            return progress
        if isinstance(progress, bool) or not isinstance(progress, (int, np.integer)) or not 0 <= progress <= k:
            raise ConfigError(f"progress: expected robot {i}'s plan step, an integer in 0..{k}, received {short_repr(progress)}")
        return int(progress)

    def steps_of_position(self, i: int, position: object, holding: bool) -> tuple[int, int]:
        """The smallest and the largest step of robot ``i``'s window (known progress to its
        furthest possible step) that a robot at ``position`` may be at: within the
        tolerance of where a robot at that step stands (its plan point when ``holding``
        or at the window's end, else the segment on to the next step)."""
        p = checked_position(position)
        lo, hi = int(self.known[i]), int(max(self.reach[i], self.known[i]))
        window = self.traj.positions[i, lo: hi + 1]
        distance = distances_to_steps(window, p, holding)
        margin = ROUNDING * (self.tolerance + float(np.abs(window).max()) + float(np.abs(p).max()))
        consistent = np.flatnonzero(distance <= self.tolerance + margin)
        if len(consistent) == 0:
            raise ConfigError(f"position: expected a point within {self.tolerance:g} of robot {i}'s plan between steps {lo} and {hi}, "
                              f"received {p.tolist()} at distance {distance.min():.3g}")
        return lo + int(consistent[0]), lo + int(consistent[-1])

    # -- what they are told ---------------------------------------------------------------------
    @locked
    def answer(self, robot: int) -> Answer:
        """``go`` (up to ``until``), ``wait`` or ``done`` for one robot, from what is known now."""
        i = self.robot_index(robot)
        decision = self._current_decision()
        x = int(self.known[i])
        if decision.finished[i]:
            return self._answer(i, "done", x)
        if not decision.moving[i]:
            return self._answer(i, "wait", x)
        until = self.horizon(i)
        if until > self.reach[i]:
            self.reach[i] = until
        return self._answer(i, "go", until)

    @locked
    def answers(self) -> list[Answer]:
        """The answer of every robot (one decision round)."""
        return [self.answer(i) for i in range(self.traj.n_robots)]

    def _answer(self, i: int, action: str, until: int) -> Answer:
        return Answer(i, action, until, int(self.known[i]), self.traj.positions[i, until].copy())

    @locked
    def decision(self) -> Decision:
        """The executor's decision step on what is known (cached until a report adds something)."""
        return self._current_decision()

    def _current_decision(self) -> Decision:
        """:meth:`decision`, for a caller that holds the lock."""
        if self._decision is None:
            self._decision = self.decide()
        return self._decision

    def decide(self) -> Decision:
        """Flip round and Eq. 1 (:meth:`PlanExecutor.decide`) on the known progress; obstacles
        whose other robot may already have reached them are not offered for a flip."""
        state = self.execution_state
        state.x = self.known.copy()
        if self.executor.variant.method is Method.RMTRACK:  # no flips: Eq. 1 only
            decision = self.executor.decide(state, self.rounds)
            self.rounds += 1
            return decision
        tried, unsafe = state.tried, self.unsafe_to_flip()
        state.tried = tried | unsafe
        offered = state.tried.copy()
        try:
            decision = self.executor.decide(state, self.rounds)
        finally:
            state.tried = tried | (state.tried & ~offered)
        self.rounds += 1
        return decision

    def unsafe_to_flip(self) -> np.ndarray:
        """Per obstacle: its label robot may have reached it (furthest step ≥ its first step in it)."""
        s, labels, first = self.space, self.execution_state.labels, self._first_sides
        active = np.where(s.side_other[first] == labels, first, first + 1)
        return self.reach[labels] >= s.side_other_lo[active]

    def horizon(self, i: int) -> int:
        """The furthest step robot ``i`` may advance to now: before the first column where
        Eq. 1 stops it, given the others' known progress (at most ``lookahead`` steps
        ahead — or one step past the furthest step its latest report lets it stand at, if
        that is further — and at most its goal step). ``O(log P + entries in the window)``:
        a short window's entries are scanned in plain Python, a long one's vectorized."""
        x = int(self.known[i])
        goal = int(self.traj.lengths[i])
        until = goal if self.lookahead is None else min(goal, max(x + self.lookahead, int(self.standing[i]) + 1))
        e = self._entries
        lo, hi = e.bounds[i], e.bounds[i + 1]
        first = bisect.bisect_right(e.cols, x, lo, hi)
        last = bisect.bisect_right(e.cols, until, first, hi)
        if last - first <= SCAN_ROWS:  # the first blocked entry has the smallest column: its rows are sorted
            labels, known = self.execution_state.labels, self.known
            for row in range(first, last):
                other = e.others[row]
                if labels[e.obstacles[row]] == other and e.tops[row] >= known[other]:
                    return min(until, e.cols[row] - 1)
            return until
        rows = slice(first, last)
        side, col, top, other = e.side[rows], e.col[rows], e.top[rows], e.other[rows]
        blocked = (self.execution_state.labels[side // 2] == other) & (top >= self.known[other])
        return min(until, int(col[blocked].min()) - 1) if blocked.any() else until

    # -- lifelong plans -----------------------------------------------------------------------------
    @locked
    def append_plan(self, robot: int, path: object) -> int:
        """Give robot ``robot``, known at its goal, a further plan: ``path`` ``(m + 1, 2)``
        whose first point is its goal (within ``position_tolerance``; the goal itself is
        kept) becomes plan steps ``K + 1 … K + m``. The robot yields in the collision
        regions of the new part where that order is admissible, else passes first (see
        *Lifelong plans* in the module docstring). Returns the robot's new goal step; a
        one-line error when the robot is not known at its goal, the path is malformed, or
        a region has no admissible order (a robot would wait for ever, or the segment
        graph would close a cycle).
        """
        i = self.robot_index(robot)
        goal = int(self.traj.lengths[i])
        if self.known[i] < goal:
            raise ConfigError(f"append_plan: expected robot {i} known at its goal step {goal}, received it known at step {int(self.known[i])}")
        steps = appended_steps(path, self.traj.positions[i, goal], self.tolerance, i)
        if not isinstance(self.executor.times, KnownProbabilities):
            raise ConfigError("append_plan: expected a supervisor with known disturbance probabilities, received a learned estimate")
        width = max(self.traj.positions.shape[1], goal + len(steps) + 1)
        positions, probability = padded(self.traj.positions, width), padded(self.executor.probability, width)
        positions[i, goal + 1:] = steps[np.minimum(np.arange(width - goal - 1), len(steps) - 1)]
        lengths = self.traj.lengths.copy()
        lengths[i] = goal + len(steps)
        self._change_plan(i, positions, lengths, probability, "append_plan")
        self.execution_state.arrival[i] = -1
        return int(lengths[i])

    @locked
    def cut_plan(self, robot: int, step: int) -> int:
        """End robot ``robot``'s plan at ``step`` (a new obstacle beyond it): it parks at
        that step's point for good. ``step`` may not be below the furthest step the robot
        may have reached (its granted ``until``). Returns the new goal step; a one-line
        error when the step is out of range or a region the cut changes has no admissible
        order (the parked robot would keep another waiting for ever, or the segment graph
        would close a cycle; see *Lifelong plans* in the module docstring).
        """
        i = self.robot_index(robot)
        goal, reached = int(self.traj.lengths[i]), int(max(self.reach[i], self.known[i]))
        if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or not reached <= step <= goal:
            raise ConfigError(f"cut_plan: expected a step of robot {i}'s plan from {reached} (the furthest it may have reached) "
                              f"to {goal}, received {short_repr(step)}")
        if step < goal:
            positions = self.traj.positions.copy()
            positions[i, step + 1:] = positions[i, step]
            lengths = self.traj.lengths.copy()
            lengths[i] = step
            self._change_plan(i, positions, lengths, self.executor.probability, "cut_plan")
        return int(step)

    def _change_plan(self, i: int, positions: np.ndarray, lengths: np.ndarray, probability: np.ndarray, what: str) -> None:
        """Rebuild the coordination space for robot ``i``'s new plan, carry the labels over,
        choose the passing orders the change leaves open, then switch to it all (nothing
        changes when a check refuses; see *Lifelong plans* in the module docstring)."""
        traj = Trajectories(positions, lengths, self.traj.radius, self.traj.dt)
        cells = {pair: c for pair, c in self._plan_cells().items() if i not in pair}  # the others' plans are as they were
        cells.update(pair_cells(traj, robot=i))
        space = space_of_cells(traj, cells, check_plan=False)
        labels, tried, changed = carried_labels(self.traj, self.space, self.execution_state, traj, space, i)
        layout = build_segment_layout(space, Resolution.EXACT)
        try:
            detector = IncrementalCycleDetector(layout, labels, self.known)
        except InfeasibleError:
            raise InfeasibleError(f"{what}: expected robot {i}'s new plan to keep the segment graph acyclic, received a cycle") from None
        self._settle_orders(i, space, labels, settled_regions(space, labels, changed, i), detector, what)
        times = self.executor.times if probability is self.executor.probability else KnownProbabilities(probability, traj.dt)
        exact = self.executor.resolution is Resolution.EXACT
        executor = dataclasses.replace(self.executor, traj=traj, space=space, probability=probability, times=times,
                                       layout=layout if exact else None)
        orders = None
        if executor.variant.method is Method.OPTIMAL:
            orders = OptimalOrders(space, layout, executor.optimal, traj.dt, detector=detector)
        self.executor, self.traj, self.space = executor, traj, space
        self.execution_state = dataclasses.replace(self.execution_state, labels=labels, tried=tried, rule=ActionRule(space),
                                                   detector=flip_detector(executor, detector), orders=orders)
        self._entries = ProfileEntries.of(space)
        self._first_sides = 2 * np.arange(space.n_obstacles)
        self._cells = cells
        self._decision = None

    def _plan_cells(self) -> dict[tuple[int, int], np.ndarray]:
        """The cells of every pair of the current plan (:func:`~.coordination_space.pair_cells`;
        computed at the first change, then carried from change to change)."""
        if self._cells is None:
            self._cells = pair_cells(self.traj)
        return self._cells

    def _settle_orders(self, i: int, space: CoordinationSpace, labels: np.ndarray, regions: np.ndarray,
                       detector: IncrementalCycleDetector, what: str) -> None:
        """Give each of ``regions`` (in index order) its carried label if that order is
        *admissible*, else the other robot; ``labels`` and ``detector`` follow every flip
        made. Admissible: the order is not broken (:meth:`_order_broken`) and the active
        segment graph stays acyclic. When an appended robot ``i`` may pass first in a
        region but for a cycle, :meth:`_pass_first_earlier` tries reordering the regions
        before it. A region with no admissible order refuses the change with a one-line
        error giving both reasons."""
        appended = bool(space.lengths[i] > self.traj.lengths[i])
        for obstacle in regions.tolist():
            carried = int(labels[obstacle])
            other = int(space.robot_i[obstacle] + space.robot_j[obstacle]) - carried
            reasons = []
            for label in (carried, other):
                reason = self._order_broken(space, obstacle, label) or self._cycle_closed(space, labels, obstacle, label, detector)
                if reason is None:
                    labels[obstacle] = label
                    break
                reasons.append(reason)
            else:
                if not (appended and self._pass_first_earlier(i, space, labels, regions, obstacle, detector)):
                    raise InfeasibleError(f"{what}: {reasons[0]}; with robot {other} first: {reasons[1]}")

    def _order_broken(self, space: CoordinationSpace, obstacle: int, label: int) -> str | None:
        """Why robot ``label`` may not pass first in ``obstacle`` whatever the other orders
        (``None``: it may). The robot passing first parks inside: its waiter would wait for
        ever. A granted column of the waiter (``≤ reach``) whose highest cell is not below
        the label robot's known step: Eq. 1's invariant could be broken already."""
        side = side_with_other(space, obstacle, label)
        waiter = int(space.side_waiter[side])
        top = space.side_profile(side)
        if top.max() >= space.lengths[label]:
            return (f"expected robot {label}'s plan to end clear of robot {waiter}'s remaining plan, "
                    f"received robot {waiter} waiting for ever from its step {int(space.side_lo[side])}")
        columns = np.arange(space.side_lo[side], space.side_hi[side] + 1)
        crossing = (columns <= self.reach[waiter]) & (top >= self.known[label])
        if crossing.any():
            return (f"expected robot {label} past robot {waiter}'s step {int(columns[crossing][0])}, "
                    f"received it known at step {int(self.known[label])} within 2r of it")
        return None

    def _cycle_closed(self, space: CoordinationSpace, labels: np.ndarray, obstacle: int, label: int,
                      detector: IncrementalCycleDetector) -> str | None:
        """Make ``label`` pass first in ``obstacle`` in ``detector`` unless that closes a cycle
        in the active segment graph (known progress); the reason when it does."""
        if labels[obstacle] == label or detector.try_flip(obstacle, label, self.known):
            return None
        waiter = int(space.robot_i[obstacle] + space.robot_j[obstacle]) - label
        return f"expected robot {label} to pass robot {waiter} first without a cycle in the segment graph, received a cycle"

    def _pass_first_earlier(self, i: int, space: CoordinationSpace, labels: np.ndarray, regions: np.ndarray,
                            obstacle: int, detector: IncrementalCycleDetector) -> bool:
        """Let the appended robot ``i`` pass first in ``obstacle``, whose other order is
        broken, by letting it pass first also in the regions of ``regions`` it yields in and
        enters before it clears ``obstacle`` — earliest first, each flip admissible — until
        ``obstacle``'s flip closes no cycle. Returns whether it does (if not, the change is
        refused and these flips, made on the change's own labels and detector, are dropped)."""
        if self._order_broken(space, obstacle, i) is not None:
            return False
        own = lambda o: side_with_other(space, o, int(space.robot_i[o] + space.robot_j[o]) - i)  # noqa: E731 - i waits
        clear = int(space.side_hi[own(obstacle)])
        earlier = [o for o in regions.tolist() if labels[o] != i and space.side_lo[own(o)] <= clear and o != obstacle]
        for o in sorted(earlier, key=lambda o: int(space.side_lo[own(o)])):
            if self._order_broken(space, o, i) or self._cycle_closed(space, labels, o, i, detector):
                continue
            labels[o] = i
            if self._cycle_closed(space, labels, obstacle, i, detector) is None:
                labels[obstacle] = i
                return True
        return False

    # -- what happened ----------------------------------------------------------------------------
    @property
    @locked
    def labels(self) -> np.ndarray:
        """Current obstacle labels (the robot that passes first)."""
        return self.execution_state.labels.copy()

    @property
    @locked
    def events(self) -> list[dict]:
        """``flip``, ``flip_refused`` (and ``deadlock``: no robot may move given what is known) events so far."""
        return list(self.execution_state.events)

    @property
    @locked
    def stats(self) -> dict:
        """Counts of flips, refused flips, flip tests and their compute time."""
        return dict(self.execution_state.stats)


@dataclass(frozen=True)
class ProfileEntries:
    """Every side profile entry (waiter column ``col``, highest other-robot step ``top``,
    its ``side`` and that side's ``other`` robot), grouped by waiter and sorted by column:
    robot ``i``'s rows are ``start[i]:start[i + 1]``, so a window of its columns is two
    binary searches."""

    side: np.ndarray
    col: np.ndarray
    top: np.ndarray
    start: np.ndarray
    other: np.ndarray
    cols: list[int] = dataclasses.field(init=False, repr=False)
    """The same entries as lists (a short window is scanned in plain Python): ``col``, ``top``,
    ``other``, the obstacle of each entry's side, and ``start``."""
    tops: list[int] = dataclasses.field(init=False, repr=False)
    others: list[int] = dataclasses.field(init=False, repr=False)
    obstacles: list[int] = dataclasses.field(init=False, repr=False)
    bounds: list[int] = dataclasses.field(init=False, repr=False)

    def __post_init__(self):
        lists = dict(cols=self.col, tops=self.top, others=self.other, obstacles=self.side // 2, bounds=self.start)
        for name, values in lists.items():
            object.__setattr__(self, name, values.tolist())

    @classmethod
    def of(cls, space: CoordinationSpace) -> ProfileEntries:
        sizes = space.side_hi - space.side_lo + 1
        side = np.repeat(np.arange(len(sizes)), sizes)
        col = space.side_lo[side] + np.arange(len(side)) - space.side_offset[side]
        order = np.lexsort((col, space.side_waiter[side]))
        start = np.searchsorted(space.side_waiter[side][order], np.arange(space.n_robots + 1))
        return cls(side[order], col[order], space.profile[order], start, space.side_other[side[order]])


def plan_executor(traj: Trajectories, method: str, deadlock_check: bool, probability: float | np.ndarray,
                  resolution: str) -> PlanExecutor:
    """A :class:`PlanExecutor` on a user's plan with the given flip policy."""
    variant = Variant(choice(method, Method, "method"), arguments.flag(deadlock_check, "deadlock_check"))
    resolution = choice(resolution, Resolution, "resolution")
    p = probability_table(probability, traj)
    space: CoordinationSpace = build_coordination_space(traj)
    return PlanExecutor(traj, space, variant, KnownProbabilities(p, traj.dt), p, resolution=resolution)


def choice(value: object, options: type[Method] | type[Resolution], name: str) -> Method | Resolution:
    """``value`` as a member of the string enum ``options``, or a one-line error naming ``name``."""
    try:
        return options(value)
    except ValueError:
        raise ConfigError(f"{name}: expected one of {[o.value for o in options]}, received {short_repr(value)}") from None


def probability_table(probability: object, traj: Trajectories) -> np.ndarray:
    """``(n, K_max + 1)`` disturbance probabilities in ``[0, 1)`` from a number or a table."""
    shape = traj.positions.shape[:2]
    try:
        table = np.asarray(probability)
    except (TypeError, ValueError):  # ragged nesting
        table = np.asarray(None)
    if table.dtype.kind not in "iuf" or table.shape not in ((), shape) or not np.all((table >= 0) & (table < 1)):
        raise ConfigError(f"probability: expected a number in [0, 1) or an array {shape} of them, received {short_repr(probability)}")
    return np.broadcast_to(table.astype(float), shape).copy()


def tolerance_value(value: object) -> float:
    """``position_tolerance`` as a finite float ``≥ 0``, or a one-line error."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value) or value < 0:
        raise ConfigError(f"position_tolerance: expected a finite number ≥ 0 or None, received {short_repr(value)}")
    return float(value)


def checked_position(position: object) -> np.ndarray:
    """A reported position as 2 finite floats, or a one-line error."""
    try:
        p = np.asarray(position, dtype=float)
    except (TypeError, ValueError):
        p = np.full(1, np.nan)
    if p.shape != (2,) or not np.all(np.isfinite(p)):
        raise ConfigError(f"position: expected 2 finite numbers (x, y), received {short_repr(position)}")
    return p


def distances_to_steps(window: np.ndarray, p: np.ndarray, holding: bool) -> np.ndarray:
    """Distance from ``p`` to where a robot at each step of ``window`` ``(m, 2)`` may
    stand: the step's point when ``holding`` (and at the window's last step), else the
    segment from it to the next step (a moving robot has not yet reached the next one)."""
    to_points = np.linalg.norm(window - p, axis=1)
    if holding or len(window) == 1:
        return to_points
    to_segments = point_segment_distance(p, window[:-1], window[1:])
    return np.append(to_segments, to_points[-1])


def appended_steps(path: object, goal: np.ndarray, tolerance: float, i: int) -> np.ndarray:
    """The steps ``(m, 2)`` a path appended at robot ``i``'s goal adds, or a one-line error."""
    try:
        p = np.asarray(path, dtype=float)
    except (TypeError, ValueError):
        p = np.full(1, np.nan)
    if p.ndim != 2 or p.shape[1:] != (2,) or len(p) < 2 or not np.all(np.isfinite(p)):
        raise ConfigError(f"append_plan: expected robot {i}'s path, an (m + 1, 2) array of finite points with m ≥ 1, received {short_repr(path)}")
    gap = float(np.linalg.norm(p[0] - goal))
    if gap > tolerance * (1 + ROUNDING) + ROUNDING:
        raise ConfigError(f"append_plan: expected robot {i}'s path to start at its goal {goal.tolist()} (within {tolerance:g}), "
                          f"received a start {p[0].tolist()} at distance {gap:.3g}")
    return p[1:]


def padded(table: np.ndarray, width: int) -> np.ndarray:
    """``(n, width, …)`` copy of ``table`` whose added columns repeat each row's last entry."""
    extra = np.repeat(table[:, -1:], width - table.shape[1], axis=1)
    return np.concatenate([table, extra], axis=1)


def carried_labels(old_traj: Trajectories, old: CoordinationSpace, state: ExecutionState, new_traj: Trajectories,
                   new: CoordinationSpace, robot: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Labels, tried flags and a *changed* mask for the regions of the new plan, in which only
    ``robot``'s plan changed. A region with the same cells as an old one keeps its label
    and flag; a part of one old region (a cut) keeps that region's label; any other (new
    cells of an appended plan) goes to the other robot first: ``robot`` yields."""
    labels = np.where(new.robot_i == robot, new.robot_j, new.robot_i)
    tried, changed = np.zeros(new.n_obstacles, bool), np.ones(new.n_obstacles, bool)
    old_keys = representatives(old)
    old_of = {key: k for k, key in enumerate(old_keys)}
    new_keys = representatives(new)
    cut = new_traj.lengths[robot] < old_traj.lengths[robot]
    grids: dict[tuple[int, int], np.ndarray] = {}
    for k, key in enumerate(new_keys):
        i, j = key[0], key[1]
        if robot not in (i, j):
            parents = [old_of[key]]
        else:
            if (i, j) not in grids:
                grids[(i, j)] = ndimage.label(contact_grid(old_traj if cut else new_traj, i, j))[0]
            grid = grids[(i, j)]
            parents = [o for o, old_key in enumerate(old_keys) if old_key[:2] == (i, j)
                       and grid[old_key[2:]] == grid[key[2:]]]
        if len(parents) == 1 and (cut or new.n_cells[k] == old.n_cells[parents[0]]):
            labels[k], tried[k] = state.labels[parents[0]], state.tried[parents[0]]
            changed[k] = new.n_cells[k] != old.n_cells[parents[0]]
    return labels, tried, changed


def representatives(space: CoordinationSpace) -> list[tuple[int, int, int, int]]:
    """Per region: its pair and one of its cells, ``(i, j, k_i, k_j)`` (its first column's top cell)."""
    first = 2 * np.arange(space.n_obstacles)
    return list(zip(space.robot_i.tolist(), space.robot_j.tolist(), space.side_lo[first].tolist(),
                    space.profile[space.side_offset[first]].tolist()))


def contact_grid(traj: Trajectories, i: int, j: int) -> np.ndarray:
    """``(K_i + 1, K_j + 1)`` cells where robots ``i`` and ``j`` are closer than ``2r`` (the
    same comparison as :func:`~.coordination_space.build_coordination_space`)."""
    a, b = traj.positions[i, : traj.lengths[i] + 1], traj.positions[j, : traj.lengths[j] + 1]
    dx, dy = a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1]
    reach = 2.0 * traj.radius
    return dx * dx + dy * dy < reach * reach


def settled_regions(space: CoordinationSpace, labels: np.ndarray, changed: np.ndarray, robot: int) -> np.ndarray:
    """The regions of ``robot`` whose passing order a change must choose: those it changed,
    and those whose robot passing first parks inside (it would have to pass its own goal
    step: its waiter would wait for ever)."""
    if space.n_obstacles == 0:
        return np.zeros(0, np.intp)
    active = labels[space.side_obstacle] == space.side_other
    highest = np.maximum.reduceat(space.profile, space.side_offset)
    parked = np.zeros(space.n_obstacles, bool)
    parked[space.side_obstacle[active & (highest >= space.lengths[space.side_other])]] = True
    involved = (space.robot_i == robot) | (space.robot_j == robot)
    return np.flatnonzero(involved & (changed | parked))


def side_with_other(space: CoordinationSpace, obstacle: int, label: int) -> int:
    """The side of ``obstacle`` that is active when ``label`` passes first (its waiter is the other robot)."""
    first = 2 * obstacle
    return first if space.side_other[first] == label else first + 1


def flip_detector(executor: PlanExecutor, detector: IncrementalCycleDetector) -> IncrementalCycleDetector | None:
    """The cycle test the executor's own flips go through on a changed plan: ``detector``
    (the exact segment graph of the new plan, built on the known progress) for TFF and TFA
    with the deadlock check, and for BTPG (its offline classification holds for the plan
    it was made on only: after a change each first-come flip is checked instead); a
    detector of the method's resolution for TFF and TFA at ``definition3``; none for
    RMTRACK (no flips), the unchecked variants and ``optimal`` (its own detector:
    :class:`~.optimal.OptimalOrders`)."""
    method, checked = executor.variant.method, executor.variant.deadlock_check
    if method is Method.BTPG or (checked and method in (Method.TFF, Method.TFA) and executor.resolution is Resolution.EXACT):
        return detector
    return executor._detector(detector.labels) if method in (Method.TFF, Method.TFA) else None
