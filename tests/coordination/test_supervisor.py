"""The online RMTRACK supervisor: recorded simulations replayed through it (reports
shuffled, late, repeated), a closed loop with late, out-of-order and missing reports and
answers (no collision, no deadlock, answers never less safe than the truth), plans from
a user's CSV, position reports, bad input."""

from __future__ import annotations

import heapq
from pathlib import Path

import numpy as np
import pytest
from coordination_instances import fig2_example, line, random_instance

import robofleet
from robofleet.coordination import Supervisor
from robofleet.coordination import supervisor as supervisor_module
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.label_flipping import KnownProbabilities
from robofleet.coordination.plan_execution import Method, PlanExecutor, Variant
from robofleet.coordination.rmtrack import ActionRule
from robofleet.coordination.trajectories import make_trajectories
from robofleet.core.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
FIG2_PLAN = ROOT / "scenarios" / "coordination" / "fig2_plan.csv"


def some_flips(ctx) -> bool:
    """An arbitrary flip test that depends on the state only (so a replay sees the same)."""
    return (int(ctx.side) * 7919 + int(np.sum(ctx.progress))) % 3 == 0


def injected_executor(seed: int, deadlock_check: bool, n: int = 5) -> PlanExecutor:
    traj, space, layout = random_instance(np.random.default_rng(seed), n, ring=True)
    p = np.full(traj.positions.shape[:2], 0.3)
    return PlanExecutor(traj, space, Variant(Method.TFF, deadlock_check), KnownProbabilities(p, traj.dt), p, layout=layout,
                        flip_test=some_flips)


def flip_log(events):
    return [(e["kind"], e["robot"], e["obstacle"]) for e in events if e["kind"] in ("flip", "flip_refused")]


def replay(sup: Supervisor, progress: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, list]:
    """Feed every recorded step's progress, robots in a random order, with repeated stale
    reports interleaved; answer every robot once all of the step's reports are in."""
    n = progress.shape[1]
    waits, flips = [], []
    for t in range(len(progress)):
        for i in rng.permutation(n).tolist():
            if t > 0 and rng.random() < 0.3:
                sup.report(i, progress=int(progress[max(0, t - int(rng.integers(1, 6))), i]))
            sup.report(i, progress=int(progress[t, i]), holding=True)
        before = len(sup.events)
        answers = [sup.answer(i) for i in rng.permutation(n).tolist()]
        waits.append([a.action == "wait" for a in sorted(answers, key=lambda a: a.robot)])
        flips += [(t, *f) for f in flip_log(sup.events[before:])]
    return np.array(waits), flips


def recorded_flips(events):
    return [(e["step"], e["kind"], e["robot"], e["obstacle"]) for e in events if e["kind"] in ("flip", "flip_refused")]


@pytest.mark.parametrize("overrides", [{}, {"policy.method": "tfa", "robots.count": 8}, {"policy.deadlock_check": False, "robots.count": 8}])
def test_replaying_recorded_simulations_gives_the_same_decisions(overrides):
    spec = robofleet.load_scenario("coordination/x_corridor_5_tff", overrides)
    for seed in (0, 1):
        trace = robofleet.simulate(spec, seed=seed)
        progress, recorded = trace.arrays["progress"][..., 0], trace.arrays["waiting"][..., 0]
        sup = Supervisor.from_scenario(spec, seed)
        waits, flips = replay(sup, progress, np.random.default_rng(seed))
        assert np.array_equal(waits, recorded)
        assert flips == recorded_flips(trace.events) and len(flips) > 0


@pytest.mark.parametrize("deadlock_check", [False, True])
def test_replaying_runs_with_injected_flips_gives_the_same_decisions(deadlock_check):
    flips = 0
    for seed in range(5):
        executor = injected_executor(seed, deadlock_check, n=6)
        run = executor.run(seed, 3000)
        sup = Supervisor(executor.traj, executor=executor)
        waits, replayed = replay(sup, run.progress, np.random.default_rng(seed))
        assert np.array_equal(waits, run.waiting) and replayed == recorded_flips(run.events)
        assert any(e["kind"] == "deadlock" for e in sup.events) == run.deadlock
        flips += len(replayed)
    assert flips > 0


@pytest.mark.parametrize("deadlock_check", [False, True])
def test_the_fig5_flip_deadlocks_unchecked_and_is_refused_checked_in_the_replay_too(deadlock_check):
    traj = fig2_example()
    space = build_coordination_space(traj)
    p = np.zeros(traj.positions.shape[:2])
    executor = PlanExecutor(traj, space, Variant(Method.TFF, deadlock_check), KnownProbabilities(p, traj.dt), p,
                            flip_test=lambda ctx: (ctx.waiter, ctx.other) == (0, 1),
                            disturbed=lambda t, x: np.array([False, t < 60, False]))
    run = executor.run(0, 2000)
    sup = Supervisor(traj, executor=executor)
    waits, replayed = replay(sup, run.progress, np.random.default_rng(0))
    assert np.array_equal(waits, run.waiting) and replayed == recorded_flips(run.events)
    kinds = [e["kind"] for e in sup.events]
    if deadlock_check:
        assert kinds.count("flip_refused") == 1 and "deadlock" not in kinds and run.finished
    else:
        assert kinds.count("flip") == 1 and "deadlock" in kinds and run.deadlock


class Network:
    """Messages delivered after random delays (so out of order), and dropped while a
    robot is in a black-out window."""

    def __init__(self, rng, max_delay, blackouts):
        self.rng, self.max_delay, self.blackouts, self.queue = rng, max_delay, blackouts, []

    def silent(self, robot, t):
        return any(r == robot and a <= t < b for r, a, b in self.blackouts)

    def send(self, t, robot, payload):
        if not self.silent(robot, t):
            heapq.heappush(self.queue, (t + int(self.rng.integers(0, self.max_delay + 1)), float(self.rng.random()), robot, payload))

    def due(self, t):
        ready = []
        while self.queue and self.queue[0][0] <= t:
            ready.append(heapq.heappop(self.queue))
        return [(robot, payload) for _, _, robot, payload in ready]


def closed_loop(executor: PlanExecutor, seed: int, max_delay: int = 6, max_ticks: int = 6000, lookahead: int = 10):
    """Robots execute the plan under the supervisor's answers, reports and answers late,
    out of order, and lost during black-outs; a robot acts on the last answer it got."""
    traj, rng = executor.traj, np.random.default_rng(seed)
    n = traj.n_robots
    sup = Supervisor(traj, executor=executor, lookahead=lookahead)
    blackouts = [(int(r), int(a), int(a) + 150) for r, a in zip(rng.choice(n, 2, replace=False), rng.integers(0, 300, 2))]
    up, down = Network(rng, max_delay, blackouts), Network(rng, max_delay, blackouts)
    x, allowed = np.zeros(n, np.intp), np.zeros(n, np.intp)
    rule = ActionRule(executor.space)
    for t in range(max_ticks):
        for i in range(n):
            up.send(t, i, int(x[i]))
        for robot, step in up.due(t):
            sup.report(robot, progress=step)
            answer = sup.answer(robot)
            if answer.go and rng.random() < 0.1:  # the horizon never shrinks nor runs into a column Eq. 1 would stop, on the TRUE progress
                assert x[robot] <= answer.until
                mine = executor.space.side_waiter == robot
                for c in range(int(x[robot]) + 1, answer.until + 1):
                    trial = x.copy()
                    trial[robot] = c - 1
                    assert not rule.blocking_sides(sup.labels, trial)[mine].any()
            down.send(t, robot, answer.until)
        for robot, until in down.due(t):
            allowed[robot] = until
        moving = (x < allowed) & (rng.random(n) >= executor.probability[np.arange(n), x])
        x = x + moving
        pos = traj.at(x)
        gap = np.linalg.norm(pos[:, None] - pos[None], axis=-1) + 1e9 * np.eye(n)
        assert gap.min() >= 2 * traj.radius, f"collision at tick {t}"
        if np.all(x >= traj.lengths):
            return sup, t
    raise AssertionError(f"not finished after {max_ticks} ticks: progress {x.tolist()} of {traj.lengths.tolist()}")


@pytest.mark.parametrize("method", ["rmtrack", "tff", "tfa"])
def test_late_out_of_order_and_missing_reports_never_collide_nor_deadlock(method):
    spec = robofleet.load_scenario("coordination/x_corridor_5_tff", {"policy.method": method, "robots.count": 8})
    sup0 = Supervisor.from_scenario(spec, 0)
    sup, ticks = closed_loop(sup0.executor, seed=3)
    assert ticks > int(sup.traj.lengths.max())
    if method != "rmtrack":
        assert sup.stats["tests"] > 0


def test_every_flip_tried_under_late_reports_stays_safe_and_deadlock_free():
    """Every eligible flip wanted (the harshest flip test), one step of look-ahead so that
    flips stay possible: no collision, every robot finishes, the check refuses cycles."""
    totals = np.zeros(2, int)
    for seed in range(6):
        executor = injected_executor(seed, True, n=6)
        executor.flip_test = lambda ctx: True
        sup, _ = closed_loop(executor, seed, lookahead=1)
        totals += [sup.stats["flips"], sup.stats["refused"]]
    assert totals[0] > 0


def test_once_every_report_has_arrived_the_answers_are_those_of_the_true_state():
    """Reports of six steps in seven are lost: whenever the latest ones are in, RMTRACK's
    answers are the recorded decisions of that step."""
    spec = robofleet.load_scenario("coordination/x_corridor_5_tff", {"robots.count": 8, "policy.method": "rmtrack"})
    trace = robofleet.simulate(spec, seed=2)
    progress, recorded = trace.arrays["progress"][..., 0], trace.arrays["waiting"][..., 0]
    sup = Supervisor.from_scenario(spec, 2)
    rng = np.random.default_rng(0)
    steps = range(0, len(progress), 7)
    for t in steps:
        for i in rng.permutation(progress.shape[1]).tolist():
            sup.report(i, progress=int(progress[t, i]))
        waiting = np.array([a.action == "wait" for a in sup.answers()])
        assert np.array_equal(waiting, recorded[t])
    assert len(steps) > 100 and recorded.any()


def test_a_users_csv_plan_and_position_reports():
    sup = Supervisor.from_csv(FIG2_PLAN, radius=1.0, dt=0.1, method="tff", position_tolerance=0.1)
    traj = sup.traj
    assert sup.report(1, position=traj.positions[1, 0] + [0.06, 0.02]) == 0
    first = sup.answer(1)
    assert first.go and first.until == 10 and np.allclose(first.stop_at, traj.positions[1, 10])
    mid = traj.positions[1, 3] + 0.6 * (traj.positions[1, 4] - traj.positions[1, 3])
    assert sup.report(1, position=mid) == 3  # between steps 3 and 4, farther than 0.1 from the path before step 3
    assert sup.report(1, progress=1) == 3  # an old report changes nothing
    with pytest.raises(ConfigError, match=r"^position: expected a point within 0.1 of robot 1's plan between steps 3 and 10, "
                                         r"received \[-1.0, -6.0\] at distance 0.75$"):
        sup.report(1, position=traj.positions[1, 0])  # where it was: not where it can be now
    on_step_6 = traj.positions[1, 6] + [0.1, 0.0]  # at the tolerance: passes for a point just short of step 6
    assert sup.report(1, position=on_step_6) == 5
    assert sup.report(1, position=on_step_6, holding=True) == 6  # holding still: it stands on step 6
    with pytest.raises(ConfigError, match=r"^position: expected a point within 0.1 of robot 1's plan between steps 6 and 6"):
        sup.report(1, position=traj.positions[1, 7])  # holding at step 6, it has not moved on
    # robot 0's plan waits 8 steps at its start: standing there it may be at any of them
    assert sup.answer(0).until == 10 and sup.report(0, position=traj.positions[0, 0]) == 0


def test_a_robot_that_cannot_be_told_apart_from_its_known_step_is_granted_a_step_past_where_it_may_stand():
    """Robot 0's plan waits 8 steps at its start; with one step of look-ahead, each answer
    grants one step past the furthest one its position fits, so it walks through the
    wait (credited its first step) and is credited step 9 as soon as it stands there."""
    sup = Supervisor.from_csv(FIG2_PLAN, radius=1.0, dt=0.1, position_tolerance=0.1, lookahead=1)
    start = sup.traj.positions[0, 0]
    assert sup.answer(0).until == 1
    for step in range(1, 9):  # standing at steps 1 to 8
        assert sup.report(0, position=start, holding=True) == 0 and sup.answer(0).until == step + 1
    assert np.array_equal(sup.traj.positions[0, 8], start) and not np.array_equal(sup.traj.positions[0, 9], start)
    assert sup.report(0, position=sup.traj.positions[0, 9], holding=True) == 9


def test_a_position_on_a_path_that_backs_up_is_credited_its_first_visit():
    """Out along a line and back over the same points: a robot on its way out is never
    credited a step of the way back (another robot waiting for that step would go)."""
    out = np.linspace([0.0, 0.0], [2.0, 0.0], 9)
    traj = make_trajectories([np.vstack([out, out[-2::-1]]), line((1.0, -4.0), (1.0, 4.0), 0.25)], 0.25, 0.1)
    sup = Supervisor(traj, position_tolerance=0.05, lookahead=None)
    assert sup.answer(0).until == 16
    assert sup.report(0, position=(0.5, 0.0), holding=True) == 2
    assert sup.report(0, position=(0.75, 0.05)) == 2  # on step 3 (and 13 on the way back), moving: maybe just short of it
    assert sup.report(0, position=(2.0, 0.0), holding=True) == 8
    assert sup.answer(0).go
    assert sup.report(0, position=(1.5, -0.05), holding=True) == 10


@pytest.mark.parametrize("call, where", [
    (lambda s: s.report(7, progress=1), "robot"),
    (lambda s: s.report(0, progress=-1), "progress"),
    (lambda s: s.report(0, progress=10**6), "progress"),
    (lambda s: s.report(0), "report"),
    (lambda s: s.report(0, progress=1, position=(0, 0)), "report"),
    (lambda s: s.report(0, position=(np.nan, 0)), "position"),
    (lambda s: s.report(0, progress=1, holding="yes"), "holding"),
    (lambda s: s.answer("a"), "robot"),
    (lambda s: Supervisor(s.traj, method="fast"), "method"),
    (lambda s: Supervisor(s.traj, resolution=3), "resolution"),
    (lambda s: Supervisor(s.traj, deadlock_check="no"), "deadlock_check"),
    (lambda s: Supervisor(s.traj, probability=1.5), "probability"),
    (lambda s: Supervisor(s.traj, probability=np.nan), "probability"),
    (lambda s: Supervisor(s.traj, probability="0.1"), "probability"),
    (lambda s: Supervisor(s.traj, probability=True), "probability"),
    (lambda s: Supervisor(s.traj, probability=0.1j), "probability"),
    (lambda s: Supervisor(s.traj, probability=[[0.1], [0.1, 0.2]]), "probability"),
    (lambda s: Supervisor(s.traj, position_tolerance=np.nan), "position_tolerance"),
    (lambda s: Supervisor(s.traj, position_tolerance=-0.5), "position_tolerance"),
    (lambda s: Supervisor(s.traj, position_tolerance=np.inf), "position_tolerance"),
    (lambda s: Supervisor(s.traj, position_tolerance="0.5"), "position_tolerance"),
    (lambda s: Supervisor(s.traj, position_tolerance=True), "position_tolerance"),
    (lambda s: Supervisor(s.traj, lookahead="3"), "lookahead"),
    (lambda s: Supervisor(s.traj, lookahead=0), "lookahead"),
    (lambda s: Supervisor(s.traj, executor="mine"), "executor"),
    (lambda s: Supervisor.from_scenario(robofleet.load_scenario("avoidance/circle_swap")), "spec"),
])
def test_bad_input_is_a_one_line_error_naming_the_argument(call, where):
    sup = Supervisor.from_csv(FIG2_PLAN, radius=1.0, dt=0.1)
    with pytest.raises(ConfigError) as info:
        call(sup)
    message = str(info.value)
    assert message.startswith(where + ": expected ") and ", received " in message and "\n" not in message


@pytest.mark.parametrize("lookahead", [1, 3, None])
def test_the_horizon_scanned_in_python_is_the_vectorized_one(lookahead, monkeypatch):
    """Closed loop on a crowded plan with flips: at every answer, the horizon of every robot
    from the plain-Python scan of its window equals the vectorized one."""
    traj, space, layout = random_instance(np.random.default_rng(3), 5, ring=True)
    sup = Supervisor(traj, method="tfa", lookahead=lookahead, probability=0.3)
    rng = np.random.default_rng(4)
    x, checked = np.zeros(traj.n_robots, np.intp), 0
    for _ in range(400):
        for i in rng.permutation(traj.n_robots).tolist():
            sup.report(i, progress=int(x[i]), holding=True)
            answer = sup.answer(i)
            for j in range(traj.n_robots):
                scanned = sup.horizon(j)
                monkeypatch.setattr(supervisor_module, "SCAN_ROWS", -1)  # every window vectorized
                assert sup.horizon(j) == scanned
                monkeypatch.setattr(supervisor_module, "SCAN_ROWS", 1 << 30)  # every window scanned
                assert sup.horizon(j) == scanned
                monkeypatch.undo()
                checked += 1
            x[i] = min(answer.until, x[i] + int(rng.random() < 0.7))
        if np.all(x >= traj.lengths):
            break
    assert np.all(x >= traj.lengths) and checked > 1000
