"""Lifelong plans with several threads (the *Threads* and *Lifelong plans* claims together):
every robot driven by its own thread (report its progress, ask for its answer, try a
step), while an *appender* thread gives finished robots further plans and a *cutter*
thread cuts robots' remaining plans, each at seeded random times; seeded random sleeps
between the calls and inside every decision, the thread switch interval at 10 µs.
Changes race with reports and answers: a change read from a stale snapshot is refused.

Checked at every move, under the world's lock: no two robots closer than ``2r`` at their
true steps (on the plan of that moment), known progress never past the true one. After
every change attempt, under the supervisor's lock, and at a stall: the active segment
graph (exact resolution, on the known progress) holds no cycle. No run stalls: whenever
every thread has gone quiet while a robot is short of its goal, the supervisor's own state
still lets a robot move (:class:`~supervisor_loops.QuietRounds`: the freed robot's thread
may not have asked yet), and once the changes stop every run ends within a round budget. Every
refused change is a one-line error; half the changes (a seeded coin) are made holding
the supervisor's lock, and their refusals must leave plan, regions, labels and known
progress as they were."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from coordination_instances import line
from supervisor_loops import (QuietRounds, SleepySupervisor, contacts_at, crossing_instance, executor_for,
                             supervisor_deadlocked, waits_for, wandering_instance)
from test_supervisor_lifelong import METHODS, TOLERANCE, CycleWatch, new_leg

from robofleet.coordination import Supervisor
from robofleet.coordination.trajectories import make_trajectories
from robofleet.core.errors import ConfigError, InfeasibleError

SLEEP = 2e-4
BUDGET = 20_000
"""Robot-thread rounds in all, once the changes have stopped, within which every run must end."""


class LifelongWorld:
    """The robots' true progress on the supervisor's current plan, moved under a lock.

    Stalled: the stall rule of :class:`~supervisor_loops.QuietRounds` (every thread quiet
    for ``quiet_rounds`` rounds, a robot short of its goal, and the supervisor lets no
    robot move), or the robot threads have made ``budget`` rounds in all since the changes
    stopped; once stalled, the run stays so. Over: stalled, or the changes have stopped
    and every robot is at its goal."""

    def __init__(self, sup: Supervisor, budget: int, quiet_rounds: int = 40):
        self.sup, self.budget = sup, budget
        self.lock = threading.Lock()
        n = sup.traj.n_robots
        self.x = np.zeros(n, np.intp)
        self.quiet = QuietRounds(n, quiet_rounds)
        self.changers_left = 2
        self.rounds_after_changes = 0
        self.contacts = self.overestimates = 0
        self.stalled = self.over = False
        self.error: str | None = None

    def step(self, i: int, until: int, disturbed: bool) -> None:
        with self.lock:
            traj = self.sup.traj  # moves beyond the old goal follow an answer on the new plan
            moved = bool(self.x[i] < until and not disturbed)
            if moved:
                self.x[i] += 1
                self.contacts += contacts_at(traj, self.x)
            self.quiet.count(i, moved)
            self.overestimates += int(np.count_nonzero(self.sup.known > self.x))
            self.rounds_after_changes += self.changers_left == 0
            finished = bool((self.x >= self.sup.traj.lengths).all())
            self.stalled = self.stalled or self.rounds_after_changes > self.budget or self.quiet.stalled(self.sup, finished)
            self.over = self.over or self.stalled or (self.changers_left == 0 and finished)

    def changer_done(self) -> None:
        with self.lock:
            self.changers_left -= 1


def refused(sup: Supervisor, change, checked: bool) -> str | None:
    """Apply a plan change; ``None`` when made, else the refusal's message, which must be one
    line. ``checked``: made holding the supervisor's (re-entrant) lock, so that no other
    thread's report, flip or change lands in between, and a refusal must leave plan,
    regions, labels and known progress as they were (unchecked changes rely on the
    method's own lock alone)."""
    if not checked:
        try:
            change()
            return None
        except (ConfigError, InfeasibleError) as error:
            assert "\n" not in str(error) and str(error)
            return str(error)
    with sup._lock:
        before = (sup.traj, sup.labels, sup.space.n_obstacles, sup.known.copy(), sup.reach.copy())
        message = refused(sup, change, checked=False)
        if message:
            assert sup.traj is before[0] and sup.space.n_obstacles == before[2]
            assert np.array_equal(sup.labels, before[1])
            assert np.array_equal(sup.known, before[3]) and np.array_equal(sup.reach, before[4])
        return message


def lifelong_threaded_run(seed: int, method: str, n: int = 4, appends: int = 5, cuts: int = 4) -> dict:
    """One run: ``n`` robot threads, an appender making ``appends`` attempts and a cutter
    making ``cuts`` attempts at seeded random times; returns its counts."""
    rng = np.random.default_rng([seed, 99])
    traj = wandering_instance(rng, n, TOLERANCE)
    executor = executor_for(traj, method)
    sup = SleepySupervisor(traj, executor=executor, position_tolerance=TOLERANCE, lookahead=1 + seed % 3,
                           sleep=SLEEP, seed=seed)
    world = LifelongWorld(sup, budget=BUDGET)
    counts = dict(appends=0, cuts=0, refused=0)
    counts_lock = threading.Lock()
    watch = CycleWatch()

    def record(message: str | None, made: str) -> None:
        with counts_lock:
            counts["refused" if message else made] += 1
        with sup._lock:
            watch.check(sup)

    def guarded(body):
        def run(*args):
            try:
                body(*args)
            except BaseException as error:  # noqa: BLE001 - reported by the test
                world.error, world.over = repr(error), True
        return run

    @guarded
    def drive(i: int, rng: np.random.Generator) -> None:
        while not world.over:
            sup.report(i, progress=int(world.x[i]))
            time.sleep(rng.uniform(0, SLEEP))
            answer = sup.answer(i)
            p = sup.executor.probability[i, min(int(world.x[i]), sup.executor.probability.shape[1] - 1)]
            world.step(i, answer.until if answer.go else -1, rng.random() < p)
            if answer.action == "done":
                time.sleep(rng.uniform(0, 4 * SLEEP))

    @guarded
    def append(rng: np.random.Generator) -> None:
        left = appends
        while left and not world.over:
            time.sleep(rng.uniform(0, 20 * SLEEP))
            plan = sup.traj  # a snapshot: it may be stale by the time the change runs
            finished = np.flatnonzero(sup.known >= plan.lengths)
            if len(finished) == 0:
                continue
            i = int(rng.choice(finished))
            leg = new_leg(rng, plan.positions[i, plan.lengths[i]])
            record(refused(sup, lambda: sup.append_plan(i, leg), rng.random() < 0.5), "appends")
            left -= 1
        world.changer_done()

    @guarded
    def cut(rng: np.random.Generator) -> None:
        for _ in range(cuts):
            if world.over:
                break
            time.sleep(rng.uniform(0, 200 * SLEEP))
            i = int(rng.integers(n))
            plan, reached = sup.traj, int(max(sup.reach[i], sup.known[i]))
            step = int(min(plan.lengths[i], reached + rng.integers(0, 6)))
            record(refused(sup, lambda: sup.cut_plan(i, step), rng.random() < 0.5), "cuts")
        world.changer_done()

    threads = [threading.Thread(target=drive, args=(i, np.random.default_rng([seed, i]))) for i in range(n)]
    threads += [threading.Thread(target=append, args=(np.random.default_rng([seed, n]),)),
                threading.Thread(target=cut, args=(np.random.default_rng([seed, n + 1]),))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    waits = None
    if world.stalled:  # is the stall a cycle of waiting robots? who waits for whom?
        watch.check(sup)
        waits = dict(x=world.x.tolist(), known=sup.known.tolist(), lengths=sup.traj.lengths.tolist(), waits=waits_for(sup))
    return dict(counts, contacts=world.contacts, overestimates=world.overestimates, cycles=watch.cycles,
                stalled=world.stalled, free_when_quiet=world.quiet.free_when_quiet, error=world.error,
                rounds_after_changes=world.rounds_after_changes, waits=waits)


def threaded_runs(method: str, seeds) -> tuple[dict, list]:
    """Totals over the runs of ``seeds``, and the runs that broke a guarantee."""
    totals, bad = {"runs": 0}, []
    for seed in seeds:
        counts = lifelong_threaded_run(seed, method)
        totals["runs"] += 1
        if counts["error"] or counts["contacts"] or counts["overestimates"] or counts["cycles"] or counts["stalled"]:
            bad.append((seed, counts))
        for key in ("appends", "cuts", "refused", "contacts", "overestimates", "cycles", "stalled", "free_when_quiet"):
            totals[key] = totals.get(key, 0) + int(counts[key])
        totals["most_rounds_after_changes"] = max(totals.get("most_rounds_after_changes", 0), counts["rounds_after_changes"])
    print(method, totals)
    return totals, bad


@pytest.mark.usefixtures("fast_thread_switches")
@pytest.mark.parametrize("method", METHODS)
def test_plans_appended_and_cut_from_other_threads_never_collide_nor_stall(method):
    totals, bad = threaded_runs(method, range(6))
    assert bad == []
    assert totals["appends"] >= 15 and totals["cuts"] >= 8


@pytest.mark.slow
@pytest.mark.usefixtures("fast_thread_switches")
@pytest.mark.parametrize("method", METHODS)
def test_plans_appended_and_cut_from_other_threads_never_collide_nor_stall_on_many_seeds(method):
    totals, bad = threaded_runs(method, range(6, 40))
    assert bad == []
    assert totals["appends"] >= 85 and totals["cuts"] >= 40


def rounds(sup: Supervisor, world: LifelongWorld, robots, count: int = 1) -> None:
    """``count`` rounds of each robot thread of ``robots``, in that order: report, ask, step."""
    for _ in range(count):
        for i in robots:
            sup.report(i, progress=int(world.x[i]))
            answer = sup.answer(i)
            world.step(i, answer.until if answer.go else -1, disturbed=False)


def run_to_the_end(sup: Supervisor, world: LifelongWorld) -> None:
    while not np.all(world.x >= sup.traj.lengths):
        rounds(sup, world, range(sup.traj.n_robots))
    assert not world.stalled and world.contacts == 0


def test_a_robot_given_a_new_plan_after_every_thread_went_quiet_is_no_stall():
    # both robots at their goals for longer than the quiet rounds; the appender then gives
    # robot 0 a new leg and robot 1's thread makes its round before robot 0's thread asks:
    # every thread has been quiet and a robot is short of its goal, yet robot 0 is free
    traj = make_trajectories([line((0, 0), (3, 0), 0.3), line((0, 4), (3, 4), 0.3)], 0.5, 0.1)
    sup = Supervisor(traj, executor=executor_for(traj, "tfa"), lookahead=1)
    world = LifelongWorld(sup, budget=BUDGET)
    run_to_the_end(sup, world)
    rounds(sup, world, (0, 1), count=world.quiet.quiet_rounds)
    assert world.quiet.rounds.min() >= world.quiet.quiet_rounds and not world.stalled
    sup.append_plan(0, line((3, 0), (3, -3), 0.3))
    rounds(sup, world, (1,))
    assert not world.stalled and world.quiet.free_when_quiet == 1
    assert not supervisor_deadlocked(sup) and sup.answer(0).go
    run_to_the_end(sup, world)


def test_a_robot_freed_by_a_report_from_a_starved_thread_is_no_stall():
    # the walker (robot 1) waits for the crosser's (robot 0) very last report; the crosser
    # makes its last move and its thread is starved while the walker's makes its quiet
    # rounds, then the crosser's thread makes its rounds (its first report frees the
    # walker) while the walker's is starved: every thread quiet, the walker free
    traj = crossing_instance(np.random.default_rng(0))
    sup = Supervisor(traj, executor=executor_for(traj, "rmtrack"), lookahead=1)  # no flip: the walker waits
    world = LifelongWorld(sup, budget=BUDGET)
    while world.x[0] < sup.traj.lengths[0]:  # the crosser's last move: its goal, not yet reported
        rounds(sup, world, (0, 1))
    rounds(sup, world, (1,), count=world.quiet.quiet_rounds)  # the crosser's thread starved
    assert not sup.answer(1).go  # its last report has not arrived
    rounds(sup, world, (0,), count=world.quiet.quiet_rounds)  # the walker's thread starved
    assert not world.stalled and world.quiet.free_when_quiet == 1
    assert not supervisor_deadlocked(sup) and sup.answer(1).go
    run_to_the_end(sup, world)
