"""Closed loops through the online supervisor, for its adversarial tests.

* :func:`position_loop`: robots that report noisy positions (errors uniform in the
  tolerance disc, a quarter of them on its rim), moving between plan steps, holding
  still now and then, their answers late and lost; every tick checks that the known
  progress is a lower bound of the true one and that no two robots are in collision.
* :func:`threaded_loop`: every robot driven by its own thread (report, answer, move),
  with seeded random sleeps between and inside the supervisor's calls.

Plans: :func:`wandering_instance` (paths that back up over themselves, come back to
the very points they left, wait, and take steps both shorter and longer than the
tolerance) and :func:`crossing_instance` (a robot's last step conflicts with another
robot's path while its goal does not: the other robot waits for exactly that report).
"""

from __future__ import annotations

import functools
import heapq
import math
import threading
import time
from dataclasses import dataclass

import numpy as np
from coordination_instances import line

from robofleet.coordination import Supervisor
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.label_flipping import KnownProbabilities
from robofleet.coordination.plan_execution import Decision, Method, PlanExecutor, Variant
from robofleet.coordination.segment_graph import IncrementalCycleDetector, build_segment_layout
from robofleet.coordination.trajectories import Trajectories, first_plan_collision, make_trajectories
from robofleet.core.errors import InfeasibleError
from robofleet.core.geometry import point_segment_distance


# -- plans ------------------------------------------------------------------------------------------
def wandering_path(rng: np.random.Generator, start: np.ndarray, goal: np.ndarray, centre: np.ndarray,
                   tolerance: float) -> Legs:
    """From ``start`` to ``goal`` through random legs around ``centre``: out and back to
    the very point left, out and back to within the tolerance of it, a detour closing on
    itself, a wait; each leg with its own step length (a fifth of the tolerance to 0.35).
    Its legs, every random draw made: :meth:`Legs.points` lays its points."""
    legs = Legs(np.asarray(start, float), [])
    here = legs.start

    def walk(to):
        nonlocal here
        here = np.asarray(to, float)
        legs.legs.append((here, rng.uniform(0.2 * tolerance, 0.35)))

    walk(centre + rng.uniform(-1, 1, 2))
    for kind in rng.choice(["back", "near", "detour", "wait"], int(rng.integers(1, 4))):
        origin = here + (tolerance * rng.uniform(-1, 1, 2) if kind == "near" else 0.0)
        if kind == "wait":
            legs.legs.append((None, int(rng.integers(1, 8))))
            continue
        walk(centre + rng.uniform(-1.5, 1.5, 2))
        if kind == "detour":
            walk(centre + rng.uniform(-1.5, 1.5, 2))
        walk(origin)
    walk(np.asarray(goal, float))
    return legs


@dataclass
class Legs:
    """A path as its ``start`` and ``legs``: per leg the point ``to`` it goes to (from where
    the one before ended) and its step length, or a wait (``to`` ``None``, then the steps
    waited)."""

    start: np.ndarray
    legs: list

    def points(self) -> np.ndarray:
        """The path's points: each leg in steps of at most its step length (the last one at
        ``here + (to − here) · 1``), each wait repeating the point it waits at."""
        here = self.start
        blocks = [here[None]]
        for to, step in self.legs:
            if to is None:
                blocks.append(np.repeat(here[None], step, axis=0))
                continue
            leg = to - here
            count = max(1, math.ceil(math.sqrt(leg.dot(leg)) / step))  # np.linalg.norm of a vector, without its overhead
            blocks.append(here + leg * fractions(count))
            here = to
        return np.concatenate(blocks)

    def corners(self) -> np.ndarray:
        """``(c, 2)`` the start and the point each leg goes to: every point of the path lies on
        the polyline through them, up to the rounding of a leg's points (a few ulps)."""
        return np.array([self.start] + [to for to, _ in self.legs if to is not None])

    def ends(self) -> np.ndarray:
        """``(2, 2)`` the path's first and last points, as :meth:`points` lays them."""
        corners = self.corners()
        return np.array([self.start, corners[-2] + (corners[-1] - corners[-2]) * 1.0])


ROUNDING_MARGIN = 1e-9
"""Far more than the distance between a path's points and its corners' polyline (a few
ulps of coordinates below 10) plus the rounding of :func:`point_segment_distance`."""


def ends_surely_near_others(plans: list[Legs], clearance: float) -> bool:
    """Some start or goal is closer than ``clearance`` to another robot's path, as
    :func:`ends_clear_of_others` finds on the laid points, decided on the legs' corners:
    closer than ``clearance − ROUNDING_MARGIN`` to another path's corner polyline, it is
    closer than ``clearance`` to that path's segments (each corner segment is covered by
    the segments between its laid points to a few ulps). ``False``: not sure."""
    ends = np.concatenate([plan.ends() for plan in plans])  # robot i's at rows 2i, 2i + 1
    corners = [plan.corners() for plan in plans]
    owner = np.concatenate([np.full(len(c) - 1, j) for j, c in enumerate(corners)])
    distance = point_segment_distance(ends, np.concatenate([c[:-1] for c in corners]), np.concatenate([c[1:] for c in corners]))
    others = owner[None, :] != np.arange(len(ends))[:, None] // 2
    return bool(np.any((distance < clearance - ROUNDING_MARGIN) & others))


@functools.lru_cache(maxsize=None)
def fractions(count: int) -> np.ndarray:
    """``(count, 1)`` the fractions ``1/count … 1`` of a leg (``np.linspace``'s values), read-only."""
    values = np.linspace(0, 1, count + 1)[1:, None]
    values.flags.writeable = False
    return values


def wandering_instance(rng: np.random.Generator, n_robots: int, tolerance: float, radius: float = 0.5,
                       max_tries: int = 500) -> Trajectories:
    """A collision-free plan of :func:`wandering_path` paths from a circle (radius 4.5)
    to roughly opposite points through its centre, each robot's start and goal at least
    ``2.1 r`` from the other robots' paths, with the smallest start delays (random
    priority) that keep it collision-free, and whose plan labels leave the exact segment
    graph acyclic (a plan RMTRACK can execute: a plan whose steps pass diagonally between
    two regions is not); at least ``n − 1`` obstacles."""
    for _ in range(max_tries):
        angle = rng.permutation(n_robots) * 2 * np.pi / n_robots + rng.uniform(0, 0.5, n_robots)
        goal_angle = angle + np.pi + rng.uniform(-0.8, 0.8, n_robots)
        ring = lambda a: 4.5 * np.column_stack([np.cos(a), np.sin(a)])  # noqa: E731
        starts, goals = ring(angle), ring(goal_angle)
        plans = [wandering_path(rng, starts[i], goals[i], np.zeros(2), tolerance) for i in range(n_robots)]
        if ends_surely_near_others(plans, 2.1 * radius):  # most tries: no need to lay their points
            continue
        paths = [plan.points() for plan in plans]
        if not ends_clear_of_others(paths, 2.1 * radius):
            continue
        delayed = smallest_delays(paths, radius, rng)
        if delayed is None:
            continue
        traj = make_trajectories(delayed, radius, 0.1)
        try:
            space = build_coordination_space(traj)
            layout = build_segment_layout(space)
            IncrementalCycleDetector(layout, space.initial_labels)
        except InfeasibleError:
            continue
        if space.n_obstacles >= n_robots - 1:
            BUILT.update(traj=traj, space=space, layout=layout)
            return traj
    raise RuntimeError("no wandering instance found")


BUILT: dict = {}
"""The last instance :func:`wandering_instance` returned (``traj``), with the coordination
space and exact segment layout it built for it: :func:`executor_for` on that plan takes
them instead of building them again (both are read-only)."""


def crossing_instance(rng: np.random.Generator, pairs: int = 1, radius: float = 0.5, speed: float = 0.3) -> Trajectories:
    """Pairs of a *crosser*, whose path crosses a *walker*'s line and ends just past it
    (its last step within ``2r`` of the line, its goal not), and the walker, delayed
    to pass after it: the walker waits for the crosser's very last report."""
    paths = []
    for k in range(pairs):
        x0 = 8.0 * k
        y = rng.uniform(-1, 1)
        paths.append(line((x0 + 3 + rng.uniform(0, 1), y), (x0 - 2 * radius - rng.uniform(0.02, 0.25), y), speed))
        paths.append(line((x0, -4 + rng.uniform(-0.5, 0.5)), (x0, 4), speed))
    return make_trajectories(smallest_delays(paths, radius, rng, order=np.arange(len(paths))), radius, 0.1)


def ends_clear_of_others(paths: list[np.ndarray], clearance: float) -> bool:
    """Every start and goal at least ``clearance`` from every other robot's path (Definition 4)."""
    for i, path in enumerate(paths):
        for j, other in enumerate(paths):
            if i != j and len(other) > 1 and point_segment_distance(path[[0, -1]], other[:-1], other[1:]).min() < clearance:
                return False
    return True


def smallest_delays(paths, radius, rng, order=None, max_delay=600):
    """Each robot in turn (random priority) after the smallest start delay that keeps it
    ``2r`` from the robots placed before; ``None`` when some robot finds none."""
    placed, delayed = [], [None] * len(paths)
    for i in rng.permutation(len(paths)) if order is None else order:
        apart = np.ones(max_delay, bool)
        for other in placed:
            apart &= delays_apart(paths[i], other, 2 * radius, max_delay)
        if not apart.any():
            return None
        candidate = np.vstack([np.repeat(paths[i][:1], int(np.argmax(apart)), axis=0), paths[i]])
        placed.append(candidate)
        delayed[i] = candidate
    return delayed


def delays_apart(path: np.ndarray, other: np.ndarray, reach: float, max_delay: int) -> np.ndarray:
    """Per start delay ``d < max_delay``: whether ``path`` delayed by ``d`` steps stays
    ``reach`` from ``other`` at every step (:func:`~coordination_instances._apart` of the
    delayed path, each robot at its last point once its path ends) — all delays at once.

    With ``close[a, b]`` (``path[a]`` and ``other[b]`` closer than ``reach``, the same
    comparison as ``_apart``), the delayed robot at time ``t`` stands at
    ``path[clip(t − d, 0, P − 1)]`` and the other at ``other[min(t, Q − 1)]``, for
    ``t < max(P + d, Q)``: before it starts (``t < d``) row 0 against ``other[:min(d, Q)]``;
    then the diagonal ``b − a = d`` and, once the other has stopped, the last column from
    row ``max(0, Q − d)``; once it has stopped itself, the last row from ``P + d``."""
    p, q = len(path), len(other)
    close = np.linalg.norm(path[:, None] - other[None], axis=-1) < reach
    d = np.arange(max_delay)
    row0 = np.concatenate([[False], np.logical_or.accumulate(close[0])])  # any(close[0, :k])
    last_col = np.append(np.logical_or.accumulate(close[::-1, -1])[::-1], False)  # any(close[k:, -1])
    last_row = np.append(np.logical_or.accumulate(close[-1, ::-1])[::-1], False)  # any(close[-1, k:])
    a, b = np.nonzero(close)
    diagonal = np.zeros(max_delay, bool)
    offset = b - a
    diagonal[offset[(offset >= 0) & (offset < max_delay)]] = True
    met = (row0[np.minimum(d, q)] | diagonal | last_col[np.minimum(np.maximum(0, q - d), p)]
           | last_row[np.minimum(p + d, q)])
    return ~met


def executor_for(traj: Trajectories, method: str, probability: float | np.ndarray = 0.2) -> PlanExecutor:
    """A checked RMTRACK / RMTRACK+TFF / RMTRACK+TFA executor on the plan."""
    if BUILT.get("traj") is traj:
        space, layout = BUILT["space"], BUILT["layout"]
    else:
        space, layout = build_coordination_space(traj), None
    p = np.broadcast_to(probability, traj.positions.shape[:2]).astype(float)
    assert first_plan_collision(traj) is None
    return PlanExecutor(traj, space, Variant(Method(method), True), KnownProbabilities(p, traj.dt), p, layout=layout)


# -- position reports ---------------------------------------------------------------------------------
@dataclass
class LoopResult:
    ticks: int
    contacts: int
    overestimates: int
    stalled: bool


def error_in_disc(rng: np.random.Generator, tolerance: float, toward: np.ndarray) -> np.ndarray:
    """A point of the disc of radius ``tolerance``: uniform, on its rim one time in four,
    and one time in three pointing to ``toward`` (a later step of the plan: the error
    that best passes for progress)."""
    radius = tolerance if rng.random() < 0.25 else tolerance * np.sqrt(rng.random())
    angle = rng.uniform(0, 2 * np.pi)
    direction = np.array([np.cos(angle), np.sin(angle)])
    if rng.random() < 1 / 3 and np.linalg.norm(toward) > 0:
        direction = toward / np.linalg.norm(toward)
    return radius * direction


def contacts_at(traj: Trajectories, x: np.ndarray) -> int:
    """Pairs of robots closer than ``2r`` at their plan steps ``x`` (in one collision region)."""
    pos = traj.at(x)
    i, j = pairs_of(len(pos))
    gap = np.linalg.norm(pos[i] - pos[j], axis=-1)
    return int(np.count_nonzero(gap < 2 * traj.radius))


@functools.lru_cache(maxsize=None)
def pairs_of(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``i < j`` of ``n`` robots (``np.triu_indices``)."""
    return np.triu_indices(n, 1)


def position_loop(executor: PlanExecutor, seed: int, tolerance: float, lookahead: int | None,
                  max_delay: int = 3, max_ticks: int | None = None) -> LoopResult:
    """Robots move along their plans on the answers they receive, report noisy positions
    (between steps while moving; ``holding=True`` half the time they are at rest, after
    which they ignore the answers given before), answers arrive late or not at all."""
    traj, rng = executor.traj, np.random.default_rng(seed)
    n = traj.n_robots
    sup = Supervisor(traj, executor=executor, position_tolerance=tolerance, lookahead=lookahead)
    x, part = np.zeros(n, np.intp), np.zeros(n)  # true progress; fraction of the way to x + 1
    allowed = np.zeros(n, np.intp)
    floor, held = np.zeros(n, int), np.zeros(n, bool)  # answers older than floor are ignored; holding still
    inbox, serial, overestimates, contacts = [], 0, 0, 0
    max_ticks = max_ticks or 30 * int(traj.lengths.max()) + 300
    for tick in range(max_ticks):
        for i in rng.permutation(n).tolist():
            if rng.random() < 0.3:
                continue
            hold = bool(part[i] == 0 and rng.random() < 0.5)
            path, goal = traj.positions[i], int(traj.lengths[i])
            here = path[x[i]] + part[i] * (path[min(x[i] + 1, goal)] - path[x[i]])
            later = path[min(goal, x[i] + int(rng.integers(1, 15)))] - here
            overestimates += sup.report(i, position=here + error_in_disc(rng, tolerance, later), holding=hold) > x[i]
            serial += 1
            if hold:
                floor[i], held[i], allowed[i] = serial, True, x[i]
            answer = sup.answer(i)
            if rng.random() < 0.9:
                heapq.heappush(inbox, (tick + int(rng.integers(0, max_delay + 1)), serial, i, answer.until))
        while inbox and inbox[0][0] <= tick:
            _, sent, i, until = heapq.heappop(inbox)
            if sent >= floor[i]:
                held[i], allowed[i] = False, max(allowed[i], until)
        moving = ~held & ((part > 0) | (x < allowed)) & (rng.random(n) >= executor.probability[np.arange(n), x])
        part = np.where(moving, part + rng.uniform(0.3, 1.0, n), part)
        arrived = part >= 1
        x, part = x + arrived, np.where(arrived, 0.0, part)
        contacts += contacts_at(traj, x)
        overestimates += int(np.count_nonzero(sup.known > x))
        if np.all(x >= traj.lengths):
            return LoopResult(tick, contacts, overestimates, False)
    return LoopResult(max_ticks, contacts, overestimates, True)


# -- threads ------------------------------------------------------------------------------------------
class QuietRounds:
    """Robot-thread rounds (report, ask, step) since the last move, and the stall rule on them.

    Quiet rounds alone are no stall: a robot freed after its thread's last round — by the
    report of a robot whose thread was starved between its move and that report, or by a
    new plan given to a robot when all were at their goals — has not asked yet while the
    other threads make their rounds. So a run stalls when every thread has gone
    ``quiet_rounds`` rounds without a move, a robot is short of its goal and the
    supervisor's own state lets no robot move (:func:`supervisor_deadlocked`); a quiet
    moment with a free robot is counted (``free_when_quiet``) and the count starts again."""

    def __init__(self, n_robots: int, quiet_rounds: int = 40):
        self.rounds = np.zeros(n_robots, int)
        self.quiet_rounds = quiet_rounds
        self.free_when_quiet = 0

    def count(self, i: int, moved: bool) -> None:
        if moved:
            self.rounds[:] = 0
        else:
            self.rounds[i] += 1

    def stalled(self, sup: Supervisor, finished: bool) -> bool:
        """The stall rule, called under the world's lock (the supervisor's lock is taken
        inside it, never the other way round)."""
        if finished or self.rounds.min() < self.quiet_rounds:
            return False
        if supervisor_deadlocked(sup):
            return True
        self.free_when_quiet += 1
        self.rounds[:] = 0
        return False


class World:
    """The robots' true progress, moved under a lock; a run is over when every robot is at
    its goal, or stalled (:class:`QuietRounds`; once stalled, the run stays so)."""

    def __init__(self, sup: Supervisor, quiet_rounds: int = 40):
        self.sup, self.traj, self.lock = sup, sup.traj, threading.Lock()
        self.x = np.zeros(self.traj.n_robots, np.intp)
        self.quiet = QuietRounds(self.traj.n_robots, quiet_rounds)
        self.contacts, self.stalled, self.over, self.error = 0, False, False, None

    def step(self, i: int, until: int, disturbed: bool) -> None:
        with self.lock:
            moved = bool(self.x[i] < until and not disturbed)
            if moved:
                self.x[i] += 1
                self.contacts += contacts_at(self.traj, self.x)
            self.quiet.count(i, moved)
            finished = bool((self.x >= self.traj.lengths).all())
            self.stalled = self.stalled or self.quiet.stalled(self.sup, finished)
            self.over = self.over or self.stalled or finished


class SleepySupervisor(Supervisor):
    """A supervisor whose decisions take a random while (seeded sleeps before and after
    computing), so that other threads' reports arrive while one is being made."""

    def __init__(self, *args, sleep: float, seed: int, **kwargs):
        super().__init__(*args, **kwargs)
        self.sleep, self.rng = sleep, np.random.default_rng(seed)

    def decide(self):
        time.sleep(self.rng.uniform(0, self.sleep))
        decision = super().decide()
        time.sleep(self.rng.uniform(0, self.sleep))
        return decision


def threaded_loop(executor: PlanExecutor, seed: int, lookahead: int = 1, sleep: float = 2e-4) -> World:
    """Every robot driven by its own thread: report its progress, (random sleep) ask for its
    answer, try one step (disturbed with the plan's probability); all random draws seeded."""
    traj = executor.traj
    sup = SleepySupervisor(traj, executor=executor, lookahead=lookahead, sleep=sleep, seed=seed)
    world = World(sup)

    def drive(i: int, rng: np.random.Generator) -> None:
        try:
            while not world.over:
                sup.report(i, progress=int(world.x[i]))
                time.sleep(rng.uniform(0, sleep))
                answer = sup.answer(i)
                world.step(i, answer.until if answer.go else -1, rng.random() < executor.probability[i, world.x[i]])
        except Exception as error:  # noqa: BLE001 - reported by the test
            world.error, world.over = repr(error), True

    threads = [threading.Thread(target=drive, args=(i, np.random.default_rng([seed, i]))) for i in range(traj.n_robots)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return world


# -- stalls -------------------------------------------------------------------------------------------
def supervisor_deadlocked(sup: Supervisor) -> bool:
    """Whether the supervisor's own state lets no robot move (under its lock): no robot would
    be answered ``go`` to a step past its known one while some robot is short of its goal.
    The answers come from the cached decision while there is one (a decision kept after a
    report that should have changed it shows here), else from Eq. 1 on the current labels
    at the known progress (the flip round of the next decision may change which robot
    moves, never whether one does: the flips keep the active segment graph acyclic, and
    then Eq. 1 never stops every robot — Theorems 1–2) — Definition 1 on what it knows.

    Why the known progress is enough: a robot whose known step lags its true one stands
    within its grants, so the column after its known step was granted, and Eq. 1 never
    takes back a column a robot may have reached (the others' known progress only grows;
    a flip needs its new waiter's furthest possible step before the region; a plan change
    settles a region only with the waiter's columns up to that step clear). So when this
    holds every robot is known where it truly is and the true state is a deadlock too."""
    with sup._lock:
        decision = sup._decision
        if decision is None:
            state = sup.execution_state
            decision = Decision(*state.rule.states(state.labels, sup.known))
        free = any(sup.horizon(i) > sup.known[i] for i in np.flatnonzero(decision.moving).tolist())
        return not free and not bool(decision.finished.all())


def waits_for(sup: Supervisor) -> list[dict]:
    """Who waits for whom now (under the supervisor's lock): per side of Eq. 1 that stops its
    waiter at the known progress, the waiter, the robot passing first, the step that one
    must pass and how far it is known and planned to go — a stall's explanation."""
    with sup._lock:
        space, labels, known = sup.space, sup.execution_state.labels, sup.known.copy()
        blocking = np.flatnonzero(sup.execution_state.rule.blocking_sides(labels, known))
        rows = []
        for side in blocking.tolist():
            w, a = int(space.side_waiter[side]), int(space.side_other[side])
            column = int(known[w]) + 1
            top = int(space.profile[space.side_offset[side] + column - space.side_lo[side]])
            rows.append(dict(waiter=w, obstacle=side // 2, first=a, must_pass=top, first_known=int(known[a]),
                             first_reach=int(sup.reach[a]), first_goal=int(space.lengths[a])))
        return rows
