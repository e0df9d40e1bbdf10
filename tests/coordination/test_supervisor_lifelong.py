"""Lifelong plans through the online supervisor: plans appended for robots that have
finished and remaining plans cut at random times, in closed loops whose robots report
noisy positions and progress (late, repeated, older than what is known) and whose
answers arrive late or not at all, for every method with the deadlock check on. No two
robots ever come closer than ``2r``, known progress stays a lower bound, the active
segment graph (exact resolution, on the known progress) never holds a cycle — after
every change and every tick, so that a deadlock a later cut would dissolve is caught
too — no run stalls, and every refused change is a one-line error that leaves the
supervisor as it was."""

from __future__ import annotations

import heapq
from types import SimpleNamespace

import numpy as np
import pytest
from coordination_instances import _apart, fig2_example, line
from supervisor_loops import contacts_at, delays_apart, error_in_disc, executor_for, wandering_instance

from robofleet.coordination import Supervisor
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.segment_graph import build_segment_layout, find_cycle_nodes
from robofleet.coordination.trajectories import make_trajectories
from robofleet.core.errors import ConfigError, InfeasibleError

TOLERANCE = 0.2
METHODS = ["rmtrack", "tff", "tfa", "btpg", "optimal"]


def new_leg(rng: np.random.Generator, start: np.ndarray) -> np.ndarray:
    """A path from ``start`` to a random point of the instance's disc (a wait now and then)."""
    goal = 4.5 * np.sqrt(rng.random()) * np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
    path = line(tuple(start), tuple(goal), rng.uniform(0.15, 0.35))
    if rng.random() < 0.3:
        path = np.vstack([path[:1]] * int(rng.integers(1, 5)) + [path])
    return path


class CycleWatch:
    """Counts the labelings of the supervisor's plans whose active segment graph (exact
    resolution, on the known progress) held a cycle; the layout is rebuilt only when the
    plan changed.

    The graph is searched only when the plan or the labels changed since the last search,
    or some robot's known step went back: under one plan and one labeling, known progress
    only marks more vertices as entered, and a subgraph of an acyclic graph is acyclic, so
    no cycle can appear between two searches. A cycle present at some moment is therefore
    present at the last search before it, and the count is zero exactly when every
    moment's graph was acyclic.
    """

    def __init__(self):
        self.space, self.layout, self.cycles = None, None, 0
        self.labels, self.known = None, None

    def check(self, sup: Supervisor) -> None:
        labels, known = sup.execution_state.labels, sup.known
        if sup.space is not self.space:
            self.space, self.layout, self.labels = sup.space, build_segment_layout(sup.space), None
        elif self.labels is not None and np.array_equal(labels, self.labels) and (known >= self.known).all():
            self.known = known.copy()
            return
        self.labels, self.known = labels.copy(), known.copy()
        self.cycles += len(find_cycle_nodes(self.layout, labels, known)) > 0


def test_the_cycle_watch_counts_a_cycle_exactly_when_some_moment_holds_one():
    """Random walks over the Fig. 3 plan's labelings and progress (forward, and now and then
    back): the watch's count is non-zero exactly when a search at every moment finds a cycle."""
    space = build_coordination_space(fig2_example())
    layout = build_segment_layout(space)
    lengths = np.asarray(fig2_example().lengths)
    for seed in range(200):
        rng = np.random.default_rng(seed)
        sup = SimpleNamespace(space=space, execution_state=SimpleNamespace(labels=space.initial_labels.copy()),
                              known=np.zeros(len(lengths), np.intp))
        watch, moments_with_a_cycle = CycleWatch(), 0
        for _ in range(40):
            move = rng.random()
            if move < 0.2:
                obstacle = int(rng.integers(len(sup.execution_state.labels)))
                sup.execution_state.labels[obstacle] = rng.choice([space.robot_i[obstacle], space.robot_j[obstacle]])
            elif move < 0.25:
                sup.known = rng.integers(0, sup.known + 1)
            else:
                sup.known = np.minimum(sup.known + rng.integers(0, 3, len(lengths)), lengths)
            watch.check(sup)
            moments_with_a_cycle += len(find_cycle_nodes(layout, sup.execution_state.labels, sup.known)) > 0
        assert (watch.cycles > 0) == (moments_with_a_cycle > 0), seed


def lifelong_loop(seed: int, method: str, n: int = 4, appends: int = 6, max_delay: int = 3, cut_rate: float = 0.02) -> dict:
    """One closed loop; returns its counts (ticks, appends, cuts, refusals, contacts,
    overestimates, cycles, stalled). ``cut_rate``: chance that a robot's answer is
    followed by a cut of its remaining plan."""
    rng = np.random.default_rng(seed)
    traj = wandering_instance(rng, n, TOLERANCE)
    sup = Supervisor(traj, executor=executor_for(traj, method), position_tolerance=TOLERANCE, lookahead=1 + seed % 4)
    x, part, allowed = np.zeros(n, np.intp), np.zeros(n), np.zeros(n, np.intp)
    floor, held = np.zeros(n, int), np.zeros(n, bool)
    inbox, serial, watch = [], 0, CycleWatch()
    counts = dict(ticks=0, appends=0, cuts=0, refused=0, contacts=0, overestimates=0, cycles=0, stalled=False)
    left = appends
    for tick in range(6000):
        counts["ticks"] = tick
        for i in rng.permutation(n).tolist():
            if rng.random() < 0.3:
                continue
            path, goal = sup.traj.positions[i], int(sup.traj.lengths[i])
            hold = bool(part[i] == 0 and rng.random() < 0.5)
            if rng.random() < 0.5:
                here = path[x[i]] + part[i] * (path[min(x[i] + 1, goal)] - path[x[i]])
                sup.report(i, position=here + error_in_disc(rng, TOLERANCE, path[min(goal, x[i] + 3)] - here), holding=hold)
            else:
                sup.report(i, progress=int(max(0, x[i] - rng.integers(0, 3))), holding=False)
                if hold:
                    sup.report(i, progress=int(x[i]), holding=True)
            serial += 1
            if hold:
                floor[i], held[i], allowed[i] = serial, True, x[i]
            answer = sup.answer(i)
            if answer.action == "done" and left > 0 and rng.random() < 0.5:
                counts["appends"] += try_change(sup, lambda: sup.append_plan(i, new_leg(rng, path[goal])), counts)
                left -= 1
                watch.check(sup)
            elif rng.random() < cut_rate:
                step = int(min(sup.traj.lengths[i], max(sup.reach[i], sup.known[i]) + rng.integers(0, 6)))
                counts["cuts"] += try_change(sup, lambda: sup.cut_plan(i, step), counts)
                watch.check(sup)
            elif rng.random() < 0.9:
                heapq.heappush(inbox, (tick + int(rng.integers(0, max_delay + 1)), serial, i, answer.until))
        while inbox and inbox[0][0] <= tick:
            _, sent, i, until = heapq.heappop(inbox)
            if sent >= floor[i]:
                held[i], allowed[i] = False, max(allowed[i], until)
        lengths = sup.traj.lengths
        probability = sup.executor.probability[np.arange(n), x]
        moving = ~held & ((part > 0) | (x < np.minimum(allowed, lengths))) & (rng.random(n) >= probability)
        part = np.where(moving, part + rng.uniform(0.3, 1.0, n), part)
        arrived = part >= 1
        x, part = x + arrived, np.where(arrived, 0.0, part)
        counts["contacts"] += contacts_at(sup.traj, x)
        counts["overestimates"] += int(np.count_nonzero(sup.known > x))
        watch.check(sup)
        counts["cycles"] = watch.cycles
        if left == 0 and (x >= sup.traj.lengths).all():
            return counts
    counts["stalled"] = True
    return counts


def try_change(sup: Supervisor, change, counts: dict) -> int:
    """Apply a plan change; a refusal must be a one-line error that changes nothing."""
    before = (sup.traj.lengths.copy(), sup.labels, sup.space.n_obstacles)
    try:
        change()
        return 1
    except (ConfigError, InfeasibleError) as error:
        assert "\n" not in str(error)
        after = (sup.traj.lengths, sup.labels, sup.space.n_obstacles)
        assert np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1]) and before[2] == after[2]
        counts["refused"] += 1
        return 0


@pytest.mark.parametrize("method", METHODS)
def test_lifelong_closed_loops_never_collide_nor_stall(method):
    totals = {}
    bad = []
    for seed in range(8):
        counts = lifelong_loop(seed, method)
        if counts["contacts"] or counts["overestimates"] or counts["cycles"] or counts["stalled"]:
            bad.append((seed, counts))
        for key, value in counts.items():
            totals[key] = totals.get(key, 0) + int(value)
    print(method, totals)
    assert bad == []
    assert totals["appends"] >= 10 and totals["cuts"] >= 3


def heavy_change_stream(method: str, seeds) -> list:
    """Closed loops with twenty appends and a cut after one answer in a hundred: the
    changes keep meeting robots parked on the way of others, whose regions a change must
    reorder. Returns the runs that broke a guarantee."""
    bad = []
    for seed in seeds:
        counts = lifelong_loop(seed, method, appends=20, cut_rate=0.01)
        if counts["contacts"] or counts["overestimates"] or counts["cycles"] or counts["stalled"]:
            bad.append((seed, counts))
    return bad


@pytest.mark.parametrize("method", ["rmtrack", "btpg", "optimal"])
def test_a_heavy_stream_of_changes_never_closes_a_cycle(method):
    assert heavy_change_stream(method, range(2)) == []


@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
def test_a_heavy_stream_of_changes_never_closes_a_cycle_on_many_seeds(method):
    assert heavy_change_stream(method, range(2, 24)) == []


def two_robots_done() -> Supervisor:
    traj = make_trajectories([line((0, 0), (3, 0), 0.3), line((0, 3), (3, 3), 0.3)], 0.5, 0.1)
    sup = Supervisor(traj, method="tff")
    sup.report(1, progress=int(traj.lengths[1]), holding=True)
    return sup


@pytest.mark.parametrize("change, message", [
    (lambda s: s.append_plan(0, [[0, 0], [1, 0]]), "expected robot 0 known at its goal step 10, received it known at step 0"),
    (lambda s: s.append_plan(1, [[3, 3]]), "expected robot 1's path, an (m + 1, 2) array"),
    (lambda s: s.append_plan(1, "abc"), "expected robot 1's path"),
    (lambda s: s.append_plan(1, [[5, 5], [6, 6]]), "expected robot 1's path to start at its goal [3.0, 3.0]"),
    (lambda s: s.append_plan(1, line((3, 3), (3, 0.2), 0.3)), "expected robot 0's plan to end clear of robot 1's remaining plan"),
    (lambda s: s.cut_plan(1, 11), "cut_plan: expected a step of robot 1's plan from 10 (the furthest it may have reached) to 10"),
    (lambda s: s.cut_plan(0, -1), "cut_plan: expected a step of robot 0's plan from 0"),
    (lambda s: s.append_plan(5, [[0, 0], [1, 1]]), "robot: expected an index in 0..1"),
])
def test_bad_changes_are_one_line_errors_that_change_nothing(change, message):
    sup = two_robots_done()
    counts = {"refused": 0}
    with pytest.raises((ConfigError, InfeasibleError)) as error:
        change(sup)
    assert message in str(error.value) and "\n" not in str(error.value)
    assert try_change(sup, lambda: change(sup), counts) == 0 and counts["refused"] == 1


def test_a_cut_that_would_park_a_robot_in_another_robots_way_is_refused_once_it_may_be_inside():
    walker, crosser = line((0, -3), (0, 3), 0.3), line((-3, 0), (3, 0), 0.3)
    traj = make_trajectories([np.vstack([walker[:1]] * 15 + [walker]), crosser], 0.5, 0.1)
    sup = Supervisor(traj, method="rmtrack", lookahead=1)
    for _ in range(9):  # the crosser, first in the crossing, walks up to it
        sup.report(1, progress=sup.answer(1).until, holding=True)
    with pytest.raises(InfeasibleError, match="expected robot 1's plan to end clear of robot 0's remaining plan"):
        sup.cut_plan(1, 10)  # step 10 is within 2r of the walker's line, and the crosser may be in the region
    fresh = Supervisor(traj, method="rmtrack", lookahead=1)
    assert fresh.cut_plan(1, 10) == 10  # not yet inside: the walker goes first instead
    assert fresh.labels.tolist() == [0]


def three_robots(parker_goal: tuple[float, float], third: np.ndarray) -> Supervisor:
    """Robot 0 walking along ``y = 0`` from ``x = −6`` to ``parker_goal``, robot 1 crossing
    its path after it at ``x = −1.2`` (after waiting in a start queue) and then turning
    right along ``y = 3``, and robot 2 on the path ``third``; robots 0 and 1 have gone
    eight steps, robot 2 none."""
    parker = line((-6, 0), parker_goal, 0.3)
    crosser = np.vstack([line((-1.2, -5), (-1.2, 3), 0.3), line((-1.2, 3), (4, 3), 0.3)[1:]])
    traj = make_trajectories([parker, np.vstack([crosser[:1]] * 12 + [crosser]), third], 0.5, 0.1)
    sup = Supervisor(traj, method="rmtrack", lookahead=1)
    for _ in range(8):
        for i in (0, 1):
            sup.report(i, progress=sup.answer(i).until, holding=True)
    return sup


def acyclic(sup: Supervisor) -> bool:
    return len(find_cycle_nodes(build_segment_layout(sup.space), sup.execution_state.labels, sup.known)) == 0


def test_an_append_that_would_close_a_cycle_of_waiting_robots_is_reordered():
    # robot 2, at its goal above the others, gets a leg down x = 0.5: across robot 1's path
    # at y = 3, where it would yield, then past robot 0's goal at the origin, where it must
    # pass first (robot 0 parks there). With those orders 2 waits for 1, 1 for 0 (still in
    # their crossing when it stops short of robot 2's path) and 0 for 2, for ever
    sup = three_robots((0, 0), np.array([[0.5, 6.0]]))
    assert sup.append_plan(2, line((0.5, 6), (0.5, -5), 0.3)) == 37
    assert sup.labels.tolist() == [0, 2, 2] and acyclic(sup)  # robot 2 passes first in both new regions
    for _ in range(200):
        for i in range(3):
            answer = sup.answer(i)
            if answer.go:
                sup.report(i, progress=answer.until, holding=True)
    assert [sup.answer(i).action for i in range(3)] == ["done"] * 3


def test_a_cut_whose_only_order_closes_a_cycle_is_refused_and_changes_nothing():
    # the same three paths as plans from the start (robot 0 walking on to x = 6, robot 2
    # coming down after robot 1 has passed): cutting robot 0 at the origin parks it in robot
    # 2's way, and letting robot 2 pass first there closes the cycle 2 → 0 → 1 → 2
    faller = line((0.5, 6), (0.5, -5), 0.3)
    sup = three_robots((6, 0), np.vstack([faller[:1]] * 45 + [faller]))
    counts = {"refused": 0}
    assert try_change(sup, lambda: sup.cut_plan(0, 20), counts) == 0
    with pytest.raises(InfeasibleError, match="with robot 2 first: expected robot 2 to pass robot 0 first without a cycle"):
        sup.cut_plan(0, 20)
    assert acyclic(sup) and sup.cut_plan(0, 40) == 40  # its own goal: nothing to settle


def test_the_delays_apart_are_those_of_the_per_delay_test():
    """:func:`~supervisor_loops.delays_apart` (every start delay at once) against the
    padded-paths test of each delay in turn, on random walks that meet, wait and stop."""
    for seed in range(40):
        rng = np.random.default_rng(seed)
        path, other = (np.cumsum(rng.normal(0, 0.3, (int(rng.integers(2, 40)), 2)), axis=0) for _ in range(2))
        reach, max_delay = float(rng.uniform(0.1, 0.8)), int(rng.integers(1, 60))
        each = [_apart(np.vstack([np.repeat(path[:1], d, axis=0), path]), other, reach) for d in range(max_delay)]
        assert delays_apart(path, other, reach, max_delay).tolist() == each, seed
