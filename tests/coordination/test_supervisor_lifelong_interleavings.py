"""Lifelong plans under seeded adversarial interleavings, single-threaded (a deterministic
replay of what threads may do): every tick is a random sequence of the robots' reports
(fresh, stale by up to three steps, or lost; ``holding=True`` now and then), their
answer requests (each answer delivered after up to three ticks, or lost), their moves
(one plan step on the latest delivered ``until``, disturbed with the plan's
probability), and an appender's and a cutter's changes, in any order. Checked after
every call: the active segment graph (exact resolution, on the known progress) holds no
cycle, known progress is never past the true one; after every move: no two robots
closer than ``2r``.
Checked for liveness after every call: the supervisor's own state lets some robot move
unless every robot is known at its goal (Eq. 1 on the current labels at the known
progress: no Definition 1 deadlock on what it knows), no active region's robot passing
first parks inside it (a wait for ever that no cycle shows), and no obstacle is flipped
twice on one plan by TFF, TFA or BTPG (a passing order going back and forth); whenever no robot has moved
for :data:`QUIET_TICKS` ticks, every robot is at its goal (a stall records which robots
wait for which). :class:`ThreadLikeInterleaving` draws the orders threads produce."""

from __future__ import annotations

import numpy as np
import pytest
from supervisor_loops import (contacts_at, error_in_disc, executor_for, supervisor_deadlocked, waits_for,
                             wandering_instance)
from test_supervisor_lifelong import TOLERANCE, CycleWatch, new_leg

from robofleet.coordination import Supervisor
from robofleet.coordination.plan_execution import Method
from robofleet.core.errors import ConfigError, InfeasibleError

QUIET_TICKS = 80
"""Ticks without a move after which a run that is not over counts as stalled (an answer
is requested with chance 0.7 and lost with chance 0.1 per tick: a robot free to move
hears so within a few ticks)."""


def parked_first(sup: Supervisor) -> int:
    """Active regions whose robot passing first parks inside (its rows reach its goal step):
    their waiter would wait for ever although no cycle shows it (Claim 3)."""
    space, labels = sup.space, sup.execution_state.labels
    if space.n_obstacles == 0:
        return 0
    active = labels[space.side_obstacle] == space.side_other
    return int(np.count_nonzero(active & parks_inside(space)))


def parks_inside(space) -> np.ndarray:
    """Per side: its other robot's rows reach that robot's goal step (computed once per plan)."""
    if PARKING.get("space") is not space:
        highest = np.maximum.reduceat(space.profile, space.side_offset)
        PARKING.update(space=space, parks=highest >= space.lengths[space.side_other])
    return PARKING["parks"]


PARKING: dict = {}
"""The last plan's :func:`parks_inside` (its space and the mask)."""


class Interleaving:
    """One seeded run: the world's true progress, the answers in transit, the counts."""

    def __init__(self, seed: int, method: str, n: int, appends: int, cuts: int):
        self.rng = rng = np.random.default_rng([seed, 7])
        traj = wandering_instance(rng, n, TOLERANCE)
        probability = rng.uniform(0.0, 0.5, traj.positions.shape[:2])  # per robot and step: TFA and TFF differ
        self.sup = self.supervisor(seed, method, traj, probability)
        self.n, self.appends_left, self.cuts_left = n, appends, cuts
        self.x = np.zeros(n, np.intp)
        self.allowed = np.zeros(n, np.intp)
        self.floor, self.held = np.zeros(n, int), np.zeros(n, bool)
        self.inbox: list[tuple[int, int, int, int]] = []  # (due tick, serial, robot, until)
        self.serial = self.tick = 0
        self.watch = CycleWatch()
        self.counts = dict(calls=0, appends=0, cuts=0, refused=0, contacts=0, overestimates=0, cycles=0, parked_first=0,
                           deadlocked=0, reflips=0, stalled=0)
        self.flipped: set[int] = set()  # obstacles flipped on the current plan
        self.events_seen = 0
        self.stall: dict | None = None
        self.graph: tuple | None = None

    def supervisor(self, seed: int, method: str, traj, probability: np.ndarray) -> Supervisor:
        """The supervisor of the run (``probability``: the disturbances drawn per robot and step)."""
        return Supervisor(traj, executor=executor_for(traj, method, probability), position_tolerance=TOLERANCE,
                          lookahead=1 + seed % 2)

    def check(self) -> None:
        sup, counts = self.sup, self.counts
        counts["calls"] += 1
        counts["overestimates"] += int(np.count_nonzero(sup.known > self.x))
        graph = (id(sup.space), sup.execution_state.labels.tobytes(), sup.known.tobytes())
        if graph != self.graph:  # the active segment graph and Eq. 1 depend on these alone
            self.graph = graph
            self.watch.check(self.sup)
            self.counts["cycles"] = self.watch.cycles
            self.counts["parked_first"] += parked_first(self.sup)
            self.counts["deadlocked"] += supervisor_deadlocked(self.sup)
        self.count_reflips()

    def count_reflips(self) -> None:
        """Flips of an obstacle already flipped on the current plan (a passing order
        going back and forth: a stall no cycle shows), for the methods that flip an
        obstacle at most once (TFF, TFA, BTPG; ``optimal`` re-decides its open orders
        at every decision by design)."""
        events = self.sup.execution_state.events  # what ``sup.events`` copies (one thread here)
        if len(events) == self.events_seen:
            return
        once = self.sup.executor.variant.method is not Method.OPTIMAL
        for event in events[self.events_seen:]:
            if event["kind"] == "flip" and once:
                self.counts["reflips"] += event["obstacle"] in self.flipped
                self.flipped.add(event["obstacle"])
        self.events_seen = len(events)

    # -- events ----------------------------------------------------------------------------------
    def report(self, i: int) -> None:
        rng = self.rng
        if rng.random() < 0.5:
            self.sup.report(i, progress=int(max(0, self.x[i] - rng.integers(0, 4))))
        else:
            hold = bool(rng.random() < 0.3)
            self.sup.report(i, progress=int(self.x[i]), holding=hold)
            self.serial += 1
            if hold:
                self.floor[i], self.held[i], self.allowed[i] = self.serial, True, self.x[i]
        self.check()

    def ask(self, i: int) -> None:
        answer = self.sup.answer(i)
        self.serial += 1
        if self.rng.random() < 0.9:
            self.inbox.append((self.tick + int(self.rng.integers(0, 4)), self.serial, i, answer.until))
        self.check()

    def move(self, i: int) -> None:
        lengths, probability = self.sup.traj.lengths, self.sup.executor.probability
        p = probability[i, min(int(self.x[i]), probability.shape[1] - 1)]
        if not self.held[i] and self.x[i] < min(self.allowed[i], lengths[i]) and self.rng.random() >= p:
            self.x[i] += 1
            self.moved = True
            self.counts["contacts"] += contacts_at(self.sup.traj, self.x)

    def append(self) -> None:
        finished = np.flatnonzero(self.sup.known >= self.sup.traj.lengths)
        if self.appends_left == 0 or len(finished) == 0:
            return
        i = int(self.rng.choice(finished))
        plan = self.sup.traj
        leg = new_leg(self.rng, plan.positions[i, plan.lengths[i]])
        self.change(lambda: self.sup.append_plan(i, leg), "appends")
        self.appends_left -= 1

    def cut(self) -> None:
        if self.cuts_left == 0:
            return
        i = int(self.rng.integers(self.n))
        reached = int(max(self.sup.reach[i], self.sup.known[i]))
        step = int(min(self.sup.traj.lengths[i], reached + self.rng.integers(0, 6)))
        self.change(lambda: self.sup.cut_plan(i, step), "cuts")
        self.cuts_left -= 1

    def change(self, make, made: str) -> None:
        try:
            make()
            self.counts[made] += 1
            self.count_reflips()
            self.flipped = set()  # the regions are renumbered
        except (ConfigError, InfeasibleError) as error:
            assert "\n" not in str(error)
            self.counts["refused"] += 1
        self.check()

    def deliver(self) -> None:
        due = [m for m in self.inbox if m[0] <= self.tick]
        self.inbox = [m for m in self.inbox if m[0] > self.tick]
        for _, sent, i, until in due:
            if sent >= self.floor[i]:
                self.held[i], self.allowed[i] = False, max(self.allowed[i], until)

    # -- the run ---------------------------------------------------------------------------------
    def events(self) -> list:
        rng, events, n = self.rng, [], self.n
        coins = rng.random(2 * n + 2).tolist()  # the doubles ``2n + 2`` calls of ``rng.random()`` draw, in order
        for i in range(n):
            if coins[2 * i] < 0.7:
                events.append((self.report, i))
            if coins[2 * i + 1] < 0.7:
                events.append((self.ask, i))
            events.append((self.move, i))
        if coins[2 * n] < 0.05:
            events.append((self.append, None))
        if coins[2 * n + 1] < 0.02:
            events.append((self.cut, None))
        return [events[k] for k in rng.permutation(len(events)).tolist()]

    def run(self, max_ticks: int = 4000) -> dict:
        quiet = 0
        for self.tick in range(max_ticks):
            self.moved = False
            for event, i in self.events():
                event() if i is None else event(i)
            self.deliver()
            over = bool((self.x >= self.sup.traj.lengths).all())
            if over and self.appends_left == 0 and self.cuts_left == 0:
                break
            quiet = 0 if self.moved or over else quiet + 1
            if self.stuck(quiet):
                self.counts["stalled"] = 1
                self.stall = self.diagnosis()
                break
        self.counts["ticks"] = self.tick
        self.counts["flips"] = int(self.sup.stats.get("flips", 0))
        self.counts["flip_tests"] = int(self.sup.stats.get("tests", 0))
        return self.counts

    def stuck(self, quiet: int) -> bool:
        """No robot has moved for :data:`QUIET_TICKS` ticks (the run is not over)."""
        return quiet >= QUIET_TICKS

    def diagnosis(self) -> dict:
        sup = self.sup
        return dict(x=self.x.tolist(), known=sup.known.tolist(), reach=sup.reach.tolist(),
                    lengths=sup.traj.lengths.tolist(), allowed=self.allowed.tolist(), held=self.held.tolist(),
                    waits=waits_for(sup))


class ThreadLikeInterleaving(Interleaving):
    """The calls robot threads, an appender thread and a cutter thread make, in the orders
    threads can put them in (every call is atomic: each holds the supervisor's lock from
    start to end, with no wait inside):

    * every thread runs its rounds in order — a robot's *report, ask, move*; the
      appender's and the cutter's *read a snapshot, make the change* — while the rounds of
      different threads interleave at any event, and a thread may be starved for many
      ticks mid-round (a robot between its answer and its move, a change between its
      snapshot and its call: the change then acts on a stale snapshot) while another runs
      in a burst (scheduling weights drawn from a Dirichlet law, redrawn every 1–30 ticks);
    * a robot reports its true step (as the threaded test does), a noisy position (error
      in the tolerance disc, a third of the time pointing to a later step; ``holding=True``
      a third of the time) or a step up to three behind; it moves on the answer it got;
    * the disturbance probability is one number for every step (0.2) in half the runs, so
      that TFA's roll-outs tie, and per step in the others; look-ahead 1–3.

    A stall is a run in which no robot has moved for ``QUIET_TICKS`` ticks *and* the
    supervisor lets no robot move (a starved robot that is free to move is no stall);
    every call is checked for that deadlock anyway."""

    def __init__(self, seed: int, method: str, n: int, appends: int, cuts: int):
        super().__init__(seed, method, n, appends, cuts)
        self.queues: list[list] = [[] for _ in range(n + 2)]  # robots', appender's, cutter's pending events
        self.weights = np.ones(n + 2)
        self.redraw_at = 0
        self.snapshot: dict = {}

    def supervisor(self, seed: int, method: str, traj, probability: np.ndarray) -> Supervisor:
        """Drawn after the base run's ``probability`` (left unused in half the runs)."""
        probability = 0.2 if seed % 2 else self.rng.uniform(0.0, 0.5, traj.positions.shape[:2])
        return Supervisor(traj, executor=executor_for(traj, method, probability), position_tolerance=TOLERANCE,
                          lookahead=1 + seed % 3)

    def report(self, i: int) -> None:
        rng, traj = self.rng, self.sup.traj
        kind = rng.random()
        if kind < 0.45:
            self.sup.report(i, progress=int(self.x[i]))
        elif kind < 0.85:
            path, goal, here = traj.positions[i], int(traj.lengths[i]), int(self.x[i])
            hold = bool(rng.random() < 1 / 3)
            later = path[min(goal, here + int(rng.integers(1, 15)))] - path[here]
            self.sup.report(i, position=path[here] + error_in_disc(rng, TOLERANCE, later), holding=hold)
            self.serial += 1
            if hold:
                self.floor[i], self.held[i], self.allowed[i] = self.serial, True, self.x[i]
        else:
            self.sup.report(i, progress=int(max(0, self.x[i] - rng.integers(1, 4))))
        self.check()

    def ask(self, i: int) -> None:
        answer = self.sup.answer(i)
        self.serial += 1
        self.held[i], self.allowed[i] = False, max(self.allowed[i], answer.until)  # the thread acts on it
        self.check()

    def read_for_append(self) -> None:
        finished = np.flatnonzero(self.sup.known >= self.sup.traj.lengths)
        if len(finished):
            i = int(self.rng.choice(finished))
            plan = self.sup.traj
            self.snapshot["append"] = (i, new_leg(self.rng, plan.positions[i, plan.lengths[i]]))

    def write_append(self) -> None:
        if "append" in self.snapshot and self.appends_left:
            i, leg = self.snapshot.pop("append")
            self.change(lambda: self.sup.append_plan(i, leg), "appends")
            self.appends_left -= 1

    def read_for_cut(self) -> None:
        i = int(self.rng.integers(self.n))
        reached = int(max(self.sup.reach[i], self.sup.known[i]))
        self.snapshot["cut"] = (i, int(min(self.sup.traj.lengths[i], reached + self.rng.integers(0, 6))))

    def write_cut(self) -> None:
        if "cut" in self.snapshot and self.cuts_left:
            i, step = self.snapshot.pop("cut")
            self.change(lambda: self.sup.cut_plan(i, step), "cuts")
            self.cuts_left -= 1

    def events(self) -> list:
        rng, n = self.rng, self.n
        if self.tick >= self.redraw_at:
            self.weights = rng.dirichlet(np.full(n + 2, 0.5))
            self.redraw_at = self.tick + int(rng.integers(1, 31))
        for i in range(n):
            if not self.queues[i]:
                self.queues[i] = [(self.report, i), (self.ask, i), (self.move, i)]
        if not self.queues[n] and self.appends_left and rng.random() < 0.08:
            self.queues[n] = [(self.read_for_append, None), (self.write_append, None)]
        if not self.queues[n + 1] and self.cuts_left and rng.random() < 0.03:
            self.queues[n + 1] = [(self.read_for_cut, None), (self.write_cut, None)]
        events = []
        for _ in range(3 * n):
            ready = [k for k, queue in enumerate(self.queues) if queue]
            if not ready:
                break
            w = self.weights[ready] + 1e-3
            events.append(self.queues[ready[weighted_index(rng, w / w.sum())]].pop(0))
        return events

    def stuck(self, quiet: int) -> bool:
        return quiet >= QUIET_TICKS and supervisor_deadlocked(self.sup)


def weighted_index(rng: np.random.Generator, p: np.ndarray) -> int:
    """``rng.choice(len(p), p=p)`` without its checks of ``p``: the same index from the same
    single uniform draw (``Generator.choice``: the normalised cumulative sum, searched on
    the right)."""
    cdf = p.cumsum()
    cdf /= cdf[-1]
    return int(cdf.searchsorted(rng.random(), side="right"))


BROKEN = ("cycles", "stalled", "contacts", "overestimates", "parked_first", "deadlocked", "reflips")
"""Counts of a run that break a guarantee."""


def interleaved_runs(method: str, seeds, appends: int = 8, cuts: int = 6,
                     search: type[Interleaving] = Interleaving) -> tuple[dict, list]:
    """Totals over the seeded runs (``4 + seed % 3`` robots) and the runs that broke a
    guarantee (with a diagnosis of a stall)."""
    totals, bad = {"runs": 0}, []
    for seed in seeds:
        run = search(seed, method, 4 + seed % 3, appends, cuts)
        counts = run.run()
        totals["runs"] += 1
        for key, value in counts.items():
            totals[key] = totals.get(key, 0) + int(value)
        if any(counts[key] for key in BROKEN):
            bad.append((seed, counts, run.stall))
    return totals, bad


@pytest.mark.parametrize("method", ["tff", "tfa"])
def test_adversarial_interleavings_never_collide_close_a_cycle_nor_stall(method):
    totals, bad = interleaved_runs(method, range(4))
    print(method, totals)
    assert bad == []
    assert totals["appends"] >= 12 and totals["cuts"] >= 8 and totals["flips"] >= 4


@pytest.mark.slow
@pytest.mark.parametrize("method", ["rmtrack", "tff", "tfa", "btpg", "optimal"])
def test_adversarial_interleavings_never_collide_close_a_cycle_nor_stall_on_many_seeds(method):
    totals, bad = interleaved_runs(method, range(4, 60))
    print(method, totals)
    assert bad == []


@pytest.mark.parametrize("method", ["tff", "tfa"])
def test_thread_like_interleavings_never_collide_deadlock_nor_stall(method):
    totals, bad = interleaved_runs(method, range(3), search=ThreadLikeInterleaving)
    print(method, totals)
    assert bad == []
    assert totals["appends"] >= 9 and totals["cuts"] >= 6


@pytest.mark.slow
@pytest.mark.parametrize("method", ["rmtrack", "tff", "tfa", "btpg", "optimal"])
def test_thread_like_interleavings_never_collide_deadlock_nor_stall_on_many_seeds(method):
    totals, bad = interleaved_runs(method, range(3, 40), search=ThreadLikeInterleaving)
    print(method, totals)
    assert bad == []
