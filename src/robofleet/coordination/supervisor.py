"""An online RMTRACK supervisor (the label-flipping deadlock paper (2021), Eq. 1; Čáp,
Gregoire & Frazzoli 2016), fed what the robots report, in any order and at any rate.

Use
    ``sup = Supervisor.from_csv("plan.csv", radius=…, dt=…, method="tff")`` (or
    ``Supervisor(trajectories)``, or :meth:`Supervisor.from_scenario`); then, whenever a
    robot reports, ``sup.report(i, progress=k)`` or ``sup.report(i, position=(x, y))``, and
    ``sup.answer(i)`` tells it ``go`` (with the plan step ``until`` it may advance to) or
    ``wait`` (or ``done``). Reports only update what the supervisor knows; answers are
    computed from that knowledge, so they depend on which reports have arrived, never
    on the order in which they did.

What it knows
    For every robot the largest plan step it has reported (an older report arriving
    late changes nothing: progress only grows) — a lower bound of its true progress —
    and the furthest step it may have reached: the ``until`` of its latest answer,
    unless it has since reported that it holds still (``holding=True``: it stays at the
    reported step until it receives an answer given after that report; a robot of a
    discrete-step simulation holds between steps).

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
    given what is known now, and at most ``lookahead`` steps ahead: advancing column by column there keeps Eq. 1's invariant
    (every column ``≤ x_i`` of an obstacle labelled ``j`` lies below ``x_j``), since the
    others' progress only grows; a flip never moves it back (flips need the other robot
    to be before the obstacle).

Guarantees
    With a collision-free plan and robots that never pass their latest ``until``: no
    collision in the coordination space (Eq. 1's invariant), and, with the deadlock check
    on, every flip kept leaves the active segment graph acyclic (Theorems 1–2 with the
    exact resolution). As soon as every robot's latest report has arrived, the answers
    are those of the simulation in the same state (the tests replay recorded
    simulations through it with reports late, out of order and missing for a while).
    A robot that stops reporting can only make others wait for it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.config import ScenarioSource, load_spec
from ..core.errors import ConfigError, short_repr
from ..core.rng import resolve_seed
from .coordination_space import CoordinationSpace, build_coordination_space
from .instance import prepare_instance
from .label_flipping import KnownProbabilities
from .plan_execution import Decision, ExecutionState, Method, PlanExecutor, Variant
from .segment_graph import Resolution
from .simulation import make_executor
from .spec import Spec
from .trajectories import Trajectories, load_trajectories

DEFAULT_LOOKAHEAD = 10
"""Plan steps granted past a robot's known progress at most (1 s at the paper's Δ = 100 ms)."""


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
    """Online RMTRACK (+TFF/TFA, + the segment-graph check) over a fixed plan.

    Parameters
    ----------
    trajectories: the plan.
    method: ``"rmtrack"``, ``"tff"`` or ``"tfa"``.
    deadlock_check: refuse flips that close a cycle in the segment graph.
    probability: disturbance probability used by the flip tests' expected times, one
        number or ``(n, K_max + 1)`` per robot and plan step.
    resolution: segment-graph resolution (``"exact"`` or ``"definition3"``).
    position_tolerance: largest distance of a reported position from the robot's plan
        (default: the robot radius).
    lookahead: at most this many plan steps past its known progress are granted to a
        robot at once (``None``: up to the first column Eq. 1 would stop it). A robot
        that reports less often than every ``lookahead`` steps stops and waits for its
        next answer; a longer look-ahead leaves fewer flips possible, since a flip needs
        the other robot not yet permitted into the obstacle.
    executor: a ready :class:`~.plan_execution.PlanExecutor` on the same plan (used by
        :meth:`from_scenario`; the other parameters are then ignored).
    """

    def __init__(self, trajectories: Trajectories, *, method: str = "rmtrack", deadlock_check: bool = True,
                 probability: float | np.ndarray = 0.05, resolution: str = "exact", position_tolerance: float | None = None,
                 lookahead: int | None = DEFAULT_LOOKAHEAD, executor: PlanExecutor | None = None):
        self.executor = executor or plan_executor(trajectories, method, deadlock_check, probability, resolution)
        self.traj, self.space = self.executor.traj, self.executor.space
        self.execution_state: ExecutionState = self.executor.start(0)
        n = self.traj.n_robots
        self.known = np.zeros(n, np.intp)
        self.reach = np.zeros(n, np.intp)
        self.rounds = 0
        self._decision: Decision | None = None
        self.tolerance = float(self.traj.radius if position_tolerance is None else position_tolerance)
        if lookahead is not None and (isinstance(lookahead, bool) or not isinstance(lookahead, (int, np.integer)) or lookahead < 1):
            raise ConfigError(f"lookahead: expected an integer ≥ 1 or None, received {short_repr(lookahead)}")
        self.lookahead = lookahead
        self._entries = ProfileEntries.of(self.space)
        self._first_sides = 2 * np.arange(self.space.n_obstacles)

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
    def report(self, robot: int, *, progress: int | None = None, position: object = None, holding: bool = False) -> int:
        """Record a robot's report: its plan step ``progress`` or its ``position``.

        A report older than what is known (a smaller step) changes nothing. ``holding``:
        the robot holds still at this step until it receives an answer given after this
        report (answers given before it no longer count). Returns the step now known for
        the robot.
        """
        i = self.robot_index(robot)
        if (progress is None) == (position is None):
            raise ConfigError(f"report: expected exactly one of progress= or position=, received progress={progress!r}, position={short_repr(position)}")
        step = self.checked_step(i, progress) if progress is not None else self.step_of_position(i, position)
        if step > self.known[i]:
            self.known[i] = step
            self._decision = None
        reach = self.known[i] if holding else max(self.reach[i], self.known[i])
        if reach < self.reach[i]:  # a robot known to hold still may be offered flips again
            self._decision = None
        self.reach[i] = reach
        return int(self.known[i])

    def robot_index(self, robot: object) -> int:
        n = self.traj.n_robots
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 0 <= robot < n:
            raise ConfigError(f"robot: expected an index in 0..{n - 1}, received {short_repr(robot)}")
        return int(robot)

    def checked_step(self, i: int, progress: object) -> int:
        k = int(self.traj.lengths[i])
        if isinstance(progress, bool) or not isinstance(progress, (int, np.integer)) or not 0 <= progress <= k:
            raise ConfigError(f"progress: expected robot {i}'s plan step, an integer in 0..{k}, received {short_repr(progress)}")
        return int(progress)

    def step_of_position(self, i: int, position: object) -> int:
        """The last plan step a robot at ``position`` has passed, among the steps it can be
        at (known progress to its furthest possible step): the segment of its plan nearest
        to the position, its end only once reached (ties: the later segment)."""
        try:
            p = np.asarray(position, dtype=float)
        except (TypeError, ValueError):
            p = np.full(1, np.nan)
        if p.shape != (2,) or not np.all(np.isfinite(p)):
            raise ConfigError(f"position: expected 2 finite numbers (x, y), received {short_repr(position)}")
        lo, hi = int(self.known[i]), int(max(self.reach[i], self.known[i]))
        step, dist = nearest_step(self.traj.positions[i, lo: hi + 1], p)
        if dist > self.tolerance:
            raise ConfigError(f"position: expected a point within {self.tolerance:g} of robot {i}'s plan between steps {lo} and {hi}, "
                              f"received {p.tolist()} at distance {dist:.3g}")
        return lo + step

    # -- what they are told ---------------------------------------------------------------------
    def answer(self, robot: int) -> Answer:
        """``go`` (up to ``until``), ``wait`` or ``done`` for one robot, from what is known now."""
        i = self.robot_index(robot)
        decision = self.decision()
        x = int(self.known[i])
        if decision.finished[i]:
            return self._answer(i, "done", x)
        if not decision.moving[i]:
            return self._answer(i, "wait", x)
        until = self.horizon(i)
        self.reach[i] = max(self.reach[i], until)
        return self._answer(i, "go", until)

    def answers(self) -> list[Answer]:
        """The answer of every robot (one decision round)."""
        return [self.answer(i) for i in range(self.traj.n_robots)]

    def _answer(self, i: int, action: str, until: int) -> Answer:
        return Answer(i, action, until, int(self.known[i]), self.traj.positions[i, until].copy())

    def decision(self) -> Decision:
        """The executor's decision step on what is known (cached until a report adds something)."""
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
        ahead and its goal step). ``O(log P + entries in the window)``, vectorized."""
        x = int(self.known[i])
        until = int(self.traj.lengths[i]) if self.lookahead is None else min(int(self.traj.lengths[i]), x + self.lookahead)
        e = self._entries
        lo, hi = e.start[i], e.start[i + 1]
        rows = slice(lo + np.searchsorted(e.col[lo:hi], x, "right"), lo + np.searchsorted(e.col[lo:hi], until, "right"))
        side, col, top = e.side[rows], e.col[rows], e.top[rows]
        other = self.space.side_other[side]
        blocked = (self.execution_state.labels[side // 2] == other) & (top >= self.known[other])
        return min(until, int(col[blocked].min()) - 1) if blocked.any() else until

    # -- what happened ----------------------------------------------------------------------------
    @property
    def labels(self) -> np.ndarray:
        """Current obstacle labels (the robot that passes first)."""
        return self.execution_state.labels.copy()

    @property
    def events(self) -> list[dict]:
        """``flip``, ``flip_refused`` (and ``deadlock``: no robot may move given what is known) events."""
        return self.execution_state.events

    @property
    def stats(self) -> dict:
        """Counts of flips, refused flips, flip tests and their compute time."""
        return dict(self.execution_state.stats)


@dataclass(frozen=True)
class ProfileEntries:
    """Every side profile entry (waiter column ``col``, highest other-robot step ``top``,
    its ``side``), grouped by waiter and sorted by column: robot ``i``'s rows are
    ``start[i]:start[i + 1]``, so a window of its columns is two binary searches."""

    side: np.ndarray
    col: np.ndarray
    top: np.ndarray
    start: np.ndarray

    @classmethod
    def of(cls, space: CoordinationSpace) -> ProfileEntries:
        sizes = space.side_hi - space.side_lo + 1
        side = np.repeat(np.arange(len(sizes)), sizes)
        col = space.side_lo[side] + np.arange(len(side)) - space.side_offset[side]
        order = np.lexsort((col, space.side_waiter[side]))
        start = np.searchsorted(space.side_waiter[side][order], np.arange(space.n_robots + 1))
        return cls(side[order], col[order], space.profile[order], start)


def plan_executor(traj: Trajectories, method: str, deadlock_check: bool, probability: float | np.ndarray,
                  resolution: str) -> PlanExecutor:
    """A :class:`PlanExecutor` on a user's plan with the given flip policy."""
    try:
        variant = Variant(Method(method), bool(deadlock_check))
        resolution = Resolution(resolution)
    except ValueError:
        raise ConfigError(f"method, resolution: expected one of {[m.value for m in Method]} and one of {[r.value for r in Resolution]}, "
                          f"received {method!r}, {resolution!r}") from None
    space: CoordinationSpace = build_coordination_space(traj)
    p = probability_table(probability, traj)
    return PlanExecutor(traj, space, variant, KnownProbabilities(p, traj.dt), p, resolution=resolution)


def probability_table(probability: float | np.ndarray, traj: Trajectories) -> np.ndarray:
    """``(n, K_max + 1)`` disturbance probabilities in ``[0, 1)`` from a number or a table."""
    shape = traj.positions.shape[:2]
    table = np.asarray(probability, dtype=float)
    if table.shape not in ((), shape) or not np.all((table >= 0) & (table < 1)):
        raise ConfigError(f"probability: expected a number in [0, 1) or an array {shape} of them, received {short_repr(probability)}")
    return np.broadcast_to(table, shape).copy()


def nearest_step(path: np.ndarray, p: np.ndarray) -> tuple[int, float]:
    """Index into ``path`` ``(m, 2)`` of the last point a robot at ``p`` has passed, and
    its distance to the path (nearest segment; its end counts once reached)."""
    if len(path) == 1:
        return 0, float(np.linalg.norm(path[0] - p))
    start, seg = path[:-1], path[1:] - path[:-1]
    length2 = np.einsum("kd,kd->k", seg, seg)
    t = np.where(length2 > 0, np.einsum("kd,kd->k", p - start, seg) / np.where(length2 > 0, length2, 1.0), 1.0)
    t = np.clip(t, 0.0, 1.0)
    dist = np.linalg.norm(start + t[:, None] * seg - p, axis=1)
    k = int(np.flatnonzero(dist <= dist.min() + 1e-12)[-1])
    return k + int(t[k] >= 1.0 - 1e-12), float(dist[k])
