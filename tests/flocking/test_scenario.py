"""Scenario validation (bad input), the leader course and conditions (1)-(4) of Sec. 3.2."""

import glob
import warnings

import numpy as np
import pytest

import robofleet
from robofleet.core.errors import ScenarioError
from robofleet.flocking import patterns
from robofleet.flocking.leader import FlockingConditionWarning, RandomTurnsLeader, build_course, check_conditions, condition4_max


def load(**kw):
    return robofleet.load_scenario({"family": "flocking", **kw})


def test_duplicate_pattern_points_are_rejected_with_the_field_path():
    with pytest.raises(ScenarioError, match=r"^<mapping>: pattern\.points: expected distinct points"):
        load(pattern={"kind": "points", "points": [[-10, 5], [-20, 0], [-10, 5]]})


def test_duplicate_points_in_a_pattern_file(tmp_path):
    f = tmp_path / "dup.yaml"
    f.write_text("points: [[-10, 5], [-10, 5]]\n")
    with pytest.raises(ScenarioError, match="dup.yaml: points: expected distinct points"):  # at validation, which reads the file
        robofleet.simulate(load(pattern={"kind": "file", "path": str(f)}, duration=5), seed=1)


def test_pattern_file_relative_to_the_scenario(tmp_path):
    (tmp_path / "p.csv").write_text("-40,20\n-40,-20\n")
    (tmp_path / "s.yaml").write_text("family: flocking\npattern: {kind: file, path: p.csv}\nduration: 5\n")
    trace = robofleet.simulate(robofleet.load_scenario(tmp_path / "s.yaml"), seed=1)
    assert trace.positions.shape[1] == 3


def test_fewer_followers_than_slots():
    with pytest.raises(ScenarioError, match=r"followers\.count: expected at least as many followers as pattern slots \(6\), received 4"):
        load(pattern={"kind": "wedge"}, followers={"count": 4})


def test_more_followers_than_slots():
    with pytest.raises(ScenarioError, match=r"followers\.count: expected one follower per pattern slot"):
        load(pattern={"kind": "line"}, followers={"count": 7})


@pytest.mark.parametrize("followers", [{"speed_min": 0.0}, {"speed_max": -1.0}, {"speeds": [1, 2, 0, 1]}])
def test_speeds_must_be_positive(followers):
    with pytest.raises(ScenarioError, match="speed > 0"):
        load(pattern={"kind": "line"}, followers=followers)


def test_leader_speed_must_be_positive():
    with pytest.raises(ScenarioError, match=r"leader\.random_turns\.speed|leader.*speed"):
        load(leader={"kind": "random_turns", "speed": -1.0})


def test_unknown_option_lists_valid_values():
    with pytest.raises(ScenarioError, match="fsync.*ssync.*async"):
        load(scheduler={"kind": "sometimes"})
    with pytest.raises(ScenarioError, match="no such key"):
        load(pattern={"kind": "wedge", "colour": "red"})


def fast_leader(on_violation):
    return load(pattern={"kind": "line"}, followers={"speeds": [1.0, 2.0, 3.0, 4.0]},
                leader={"kind": "random_turns", "speed": 1.5, "turn_rate": 0.0}, duration=5,
                checks={"conditions": on_violation})


def test_leader_violating_the_conditions_warns_by_default_and_errors_when_asked():
    with pytest.warns(FlockingConditionWarning, match=r"\(1\) v_L < min v_f: 1.5 < 1"):
        trace = robofleet.simulate(fast_leader("warn"), seed=1)
    assert trace.results["condition_1"] is False
    with pytest.raises(ScenarioError, match=r"leader: expected a leader within the conditions of Sec. 3.2"):
        robofleet.simulate(fast_leader("error"), seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        robofleet.simulate(fast_leader("ignore"), seed=1)


def test_conditions_by_hand():
    rep = check_conditions(0.4, 0.01, 100.0, [1.0, 2.0], [1.5, 1.0], xi=3.0, on_violation="ignore")
    assert rep.slot_speed == pytest.approx(1.4)
    h = rep.holds
    assert h["condition_1"] and not h["condition_2"]        # 1.4 >= min v_f = 1
    assert rep.sum_k == pytest.approx(1.4 * 2.5) and not h["condition_3"]


def test_condition4_matches_a_brute_force_sweep():
    rng = np.random.default_rng(0)
    starts, ends = [], []
    for _ in range(4):
        t = rng.uniform(0, 1)
        while t < 30:
            d = rng.uniform(0.5, 2.0)
            starts.append(t); ends.append(t + d)
            t += d + rng.uniform(0, 0.5) * (rng.random() < 0.3)
    starts, ends = np.array(starts), np.array(ends)
    grid = np.linspace(0, 32, 200001)
    active = (grid[:, None] >= starts) & (grid[:, None] <= ends)
    brute = np.max(np.where(active, grid[:, None] - starts, 0.0).sum(axis=1))
    assert condition4_max(starts, ends, 0.7) == pytest.approx(0.7 * brute, rel=1e-3)


def test_random_turn_course_speed_and_turn_rate():
    course = build_course(RandomTurnsLeader(speed=0.8, turn_rate=0.05, turn_probability=0.05), speed=0.8, turn_rate=0.05,
                          start=[0.0, 0.0], heading=0.3, horizon=2000, rng=4)
    t = np.linspace(0, 2000, 40001)
    p = course.position(t)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)
    assert np.allclose(step, 0.8, rtol=1e-3)
    turn = np.diff(course.heading(t)) / np.diff(t)
    assert np.abs(turn).max() <= 0.05 + 1e-12
    assert (np.abs(turn) > 0).mean() == pytest.approx(0.5, abs=0.2)   # turning about half the time
    # heading is the direction of motion
    d = np.diff(p, axis=0)
    assert np.allclose(np.arctan2(d[:, 1], d[:, 0]), np.angle(np.exp(1j * course.heading(t[:-1] + 0.025))), atol=1e-3)


def test_scripted_course_turns_as_scripted():
    spec = robofleet.load_scenario("scenarios/flocking/scripted_leader.yaml")
    course = build_course(spec.leader, speed=spec.leader.speed, turn_rate=0.004, start=[0, 0], heading=0.0, horizon=1000)
    assert course.heading(300.0) == pytest.approx(0.0)
    assert course.heading(450.0) == pytest.approx(150 * 0.004)
    assert course.heading(1000.0) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("path", sorted(glob.glob("scenarios/flocking/*.yaml")))
def test_shipped_scenarios_load_and_run(path):
    spec = robofleet.load_scenario(path, overrides={"duration": 20})
    trace = robofleet.simulate(spec, seed=0)
    m = trace.results["n_followers"]
    assert trace.positions.shape == (21, m + 1, 2)
    assert trace.metadata["leader_index"] == 0


def test_trace_roundtrip(tmp_path):
    trace = robofleet.simulate(load(pattern={"kind": "line"}, duration=10), seed=3)
    back = robofleet.Trace.load(trace.save(tmp_path / "t"))
    assert np.array_equal(back.positions, trace.positions)
    assert back.summary()["slot_changes"] == trace.results["slot_changes"]


def test_lb_symmetry_and_axis_checks():
    assert patterns.wedge().is_lb_symmetric and patterns.wedge().n_on_axis == 0
    assert patterns.random_lb_symmetric(7, 1).n_on_axis == 1
    asym = patterns.validate_points([[-10.0, 3.0], [-12.0, -5.0]])
    assert not asym.is_lb_symmetric
    ok, reason = patterns.validate_points([[-10.0, 0.0], [-20.0, 0.0]]).supported_by_basic()
    assert not ok and "at most 1 point" in reason
    with pytest.raises(ScenarioError, match="barycenter"):
        patterns.validate_points([[-10.0, 0.0], [10.0, 0.0]])
