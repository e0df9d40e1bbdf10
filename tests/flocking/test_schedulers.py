"""Schedulers (Sec. 2, A1-A3): event-log checks, FSYNC convergence, determinism."""

import numpy as np
import pytest

import robofleet
from robofleet.flocking.leader import LeaderCourse
from robofleet.flocking.basic import BasicAlgorithm
from robofleet.flocking.model import LocalFrames
from robofleet.flocking.patterns import wedge
from robofleet.flocking.schedulers import SchedulerSpec, run


def cycles(trace):
    ev = [e for e in trace.events if e["kind"] == "cycle"]
    cols = {k: np.array([e[k] for e in ev]) for k in ev[0]}
    return cols


@pytest.fixture(scope="module")
def async_trace():
    spec = robofleet.load_scenario({
        "family": "flocking", "pattern": {"kind": "wedge"},
        "scheduler": {"kind": "async", "cycle_min": 0.3, "cycle_max": 2.0, "rigidity": 0.3, "min_move": 0.05},
        "duration": 300,
    })
    return robofleet.simulate(spec, seed=7), spec


def test_async_log_respects_a1_a2_a3(async_trace):
    trace, spec = async_trace
    c = cycles(trace)
    sched = spec.scheduler
    duration = c["t_end"] - c["t_look"]
    # A1: every cycle is finite and bounded below
    assert np.all(duration >= sched.cycle_min) and np.all(duration <= sched.cycle_max)
    for robot in np.unique(c["robot"]):
        mine = np.flatnonzero(c["robot"] == robot)
        order = mine[np.argsort(c["t_look"][mine])]
        # A3: Look and Compute take no time: the next Look starts when the previous cycle ends
        assert np.allclose(c["t_look"][order][1:], c["t_end"][order][:-1])
        # the robot is where its last Move stopped when it looks again
        assert np.allclose(c["start"][order][1:], c["end"][order][:-1], atol=1e-9)
        # each follower is activated again and again (no starvation within the horizon)
        assert len(order) >= 300 / sched.cycle_max - 2
    # A2: a Move covers at least min(delta_f, |path|) and never more than the path
    travel, length = c["travel"], c["path_length"]
    assert np.all(travel >= np.minimum(sched.min_move, length) - 1e-12)
    assert np.all(travel <= length + 1e-12)
    short = length <= sched.min_move
    assert short.any()
    assert np.allclose(c["end"][short], c["destination"][short], atol=1e-9)
    # straight moves: the robot stopped `travel` along the segment towards its destination
    moved = np.linalg.norm(c["end"] - c["start"], axis=1)
    assert np.allclose(moved, travel, atol=1e-9)
    # non-rigid: some moves stop short of a reachable destination
    speeds = np.asarray(trace.metadata["speeds"])[c["robot"] - 1]
    assert np.any((travel < length - 1e-6) & (travel < speeds * duration * 0.99))
    # asynchrony: robots are observed while moving
    assert np.mean(c["seen_moving"] > 0) > 0.5


def test_async_sampled_positions_follow_the_logged_moves(async_trace):
    trace, _ = async_trace
    c = cycles(trace)
    pos = trace.positions
    times = trace.arrays["time"]
    rng = np.random.default_rng(0)
    for k in rng.choice(len(c["robot"]), 50, replace=False):
        inside = (times >= c["t_look"][k]) & (times <= c["t_end"][k])
        for t in np.flatnonzero(inside):
            p = pos[t, c["robot"][k]]
            a, b = c["start"][k], c["end"][k]
            # on the segment start -> end
            assert np.linalg.norm(p - a) + np.linalg.norm(b - p) == pytest.approx(np.linalg.norm(b - a), abs=1e-7)


def test_ssync_activates_a_nonempty_subset_each_round_and_moves_finish_in_the_round():
    spec = robofleet.load_scenario({"family": "flocking", "pattern": {"kind": "line"},
                                    "scheduler": {"kind": "ssync", "activation_probability": 0.3}, "duration": 200})
    c = cycles(robofleet.simulate(spec, seed=3))
    rounds = np.unique(c["t_look"])
    assert np.allclose(rounds, np.arange(len(rounds)))          # a Look in every round
    per_round = np.bincount(c["t_look"].astype(int))
    assert per_round.min() >= 1 and per_round.max() <= 4
    assert 0.15 < per_round.mean() / 4 < 0.5                       # ~30 % activated (non-empty redraw)
    assert np.allclose(c["t_end"] - c["t_look"], 1.0)


def test_fsync_straight_leader_basic_forms_the_wedge_up_to_xi():
    """Sec. 4: under FSYNC with a straight leader, Algorithm 1 reaches and keeps Δ_e ≤ ξ."""
    spec = robofleet.load_scenario("scenarios/flocking/wedge_fsync_straight.yaml")
    for seed in (1, 2):
        trace = robofleet.simulate(spec, seed=seed)
        r = trace.results
        de = trace.arrays["delta_e"]
        assert r["converged_e"], seed
        assert np.all(de[-100:] <= r["xi"]), seed
        assert de[0] > 10 * r["xi"]                                    # it did have to form it
        assert r["condition_1"] and r["condition_2"] and r["condition_3"]


def test_same_seed_same_trace_different_seed_different_trace():
    spec = robofleet.load_scenario({"family": "flocking", "pattern": {"kind": "random"},
                                    "algorithm": {"kind": "randomized"}, "duration": 80})
    a, b, c = (robofleet.simulate(spec, seed=s) for s in (5, 5, 6))
    assert np.array_equal(a.positions, b.positions)
    assert a.events == b.events
    assert not np.array_equal(a.positions[:, 0], c.positions[:, 0])


def test_min_move_above_what_a_cycle_allows_is_rejected():
    from robofleet.core.errors import ScenarioError
    spec = robofleet.load_scenario({"family": "flocking", "pattern": {"kind": "line"},
                                    "followers": {"speed_min": 0.5, "speed_max": 0.6},
                                    "scheduler": {"kind": "async", "cycle_min": 0.5, "min_move": 1.0}, "duration": 10})
    with pytest.raises(ScenarioError, match="min_move"):
        robofleet.simulate(spec, seed=1)


def test_run_checks_shapes_and_speeds_at_its_boundary():
    from robofleet.core.errors import ConfigError
    pat = wedge()
    course = LeaderCourse.build([0, 0], 0.0, 0.1, np.array([10.0]), np.array([0.0]))
    frames = LocalFrames.random(6, 0)
    kw = dict(duration=2, scheduler_rng=np.random.default_rng(0), algorithm_rng=np.random.default_rng(0))
    with pytest.raises(ConfigError, match="starts"):
        run(BasicAlgorithm(), pat, frames, np.zeros((5, 2)), np.ones(6), course, SchedulerSpec(), **kw)
    with pytest.raises(ConfigError, match="speeds > 0"):
        run(BasicAlgorithm(), pat, frames, np.random.default_rng(1).uniform(0, 9, (6, 2)), np.array([1, 1, 1, 0, 1, 1.0]), course, SchedulerSpec(), **kw)
