"""Sec. 5 (hula-hoop, stripe), Sec. 6.4 (randomized) and Sec. 6.1-6.3 (more knowledge)."""

import numpy as np
import pytest

import robofleet
from robofleet.flocking import patterns
from robofleet.flocking.basic import BasicAlgorithm
from robofleet.flocking.hula_hoop import HulaHoopAlgorithm
from robofleet.flocking.leader import LeaderCourse
from robofleet.flocking.model import LocalFrames, look
from robofleet.flocking.randomized import RandomizedAlgorithm, ranking
from robofleet.flocking.schedulers import SchedulerSpec, run
from robofleet.flocking.stripe import StripeAlgorithm

ASYM = "scenarios/flocking/randomized_asymmetric.yaml"


def neighbour_band(key, side, me=0):
    """(lower, upper) of key among the observer's semi-space neighbours (decreasing order)."""
    mine = np.flatnonzero(side == side[me])
    vals = np.sort(key[mine])[::-1]
    k = int(np.flatnonzero(vals == key[me])[0])
    upper = vals[k - 1] if k > 0 else np.inf
    lower = vals[k + 1] if k + 1 < len(vals) else 0.0
    return lower, upper


@pytest.mark.parametrize("algorithm", [HulaHoopAlgorithm(), StripeAlgorithm()])
def test_moves_stay_in_the_stable_space_and_stop_at_its_boundary(algorithm):
    """Sec. 5.2 / 5.3: a follower never deliberately leaves its stable space."""
    stopped = 0
    for seed in range(150):
        rng = np.random.default_rng(seed)
        pattern = [patterns.wedge(), patterns.spread()][seed % 2]
        followers = rng.uniform(0, 300, (pattern.size, 2))
        leader = rng.uniform(0, 300, 2)
        frames = LocalFrames.random(pattern.size, rng)
        snap = look(frames, 0, leader, followers)
        decision = algorithm.decide(snap, pattern)
        y = snap.leader - snap.followers.mean(axis=0)
        y /= np.linalg.norm(y)
        lat = (snap.followers - snap.leader) @ np.array([-y[1], y[0]])
        side = np.where(np.abs(lat) <= algorithm.axis_tolerance, 0, np.where(lat > 0, 1, 2))
        if side[0] == 0:
            continue
        if isinstance(algorithm, HulaHoopAlgorithm):
            key = np.linalg.norm(snap.followers - snap.leader, axis=1)
            path_key = np.linalg.norm(decision.path - snap.leader, axis=1)
        else:
            key = np.abs(lat)
            path_key = np.abs((decision.path - snap.leader) @ np.array([-y[1], y[0]]))
        lo, hi = neighbour_band(key, side)
        assert np.all(path_key >= min(lo, key[0]) - 1e-9) and np.all(path_key <= max(hi, key[0]) + 1e-9), seed
        view = algorithm.view(snap, pattern, pattern.points, algorithm.y_axis(snap))
        target = view.slot_points[decision.slot]
        if not np.allclose(decision.destination, target):
            stopped += 1
            assert min(abs(path_key[-1] - lo), abs(path_key[-1] - hi)) <= algorithm.margin + 1e-9, seed
    assert stopped > 10  # the boundary rule is exercised


def test_hula_hoop_uses_curved_moves_when_the_segment_would_leave_the_annulus():
    alg = HulaHoopAlgorithm()
    curved = 0
    for seed in range(200):
        rng = np.random.default_rng(seed)
        pattern = patterns.wedge()
        followers = rng.uniform(0, 300, (pattern.size, 2))
        leader = rng.uniform(0, 300, 2)
        d = alg.decide(look(LocalFrames.random(6, rng), 0, leader, followers), pattern)
        if len(d.path) > 1 and np.allclose(d.destination, d.path[-1]):
            pts = np.concatenate([np.zeros((1, 2)), d.path])
            turn = np.diff(np.arctan2(*np.diff(pts, axis=0).T[::-1]))
            curved += bool(np.any(np.abs(turn) > 1e-6))
    assert curved > 0


def test_ranking_procedure():
    L, B = np.zeros(2), np.array([-10.0, 0.0])
    c = np.array([[-20.0, 5.0], [-5.0, 2.0]])
    assert ranking(c, c * [1, -1], L, B) == 0              # mirror images rank equal
    assert ranking(c, c * 0.5, L, B) == 1                   # farther from L ranks higher
    assert ranking(c * 0.5, c, L, B) == -1
    assert ranking(c, c[:1], L, B) == 1                     # size first when |C| != |D|


def mirrored_pair_run(algorithm, duration=150):
    """Fig. 14b: two followers mirror-symmetric about the leader's line of motion, with
    mirrored frames and equal speeds, two slots on the axis."""
    pattern = patterns.validate_points([[-40.0, 0.0], [-90.0, 0.0]])
    starts = np.array([[-200.0, 60.0], [-200.0, -60.0]])
    frames = LocalFrames(np.array([0.3, -0.3]), np.array([1.0, -1.0]))
    course = LeaderCourse.build([0.0, 0.0], 0.0, 0.5, np.array([duration + 2.0]), np.array([0.0]))
    spec = SchedulerSpec(kind="fsync")
    res = run(algorithm, pattern, frames, starts, np.array([2.0, 2.0]), course, spec, duration=duration,
              scheduler_rng=np.random.default_rng(0), algorithm_rng=np.random.default_rng(1))
    from robofleet.flocking.metrics import delta_series
    return delta_series(res.positions, res.headings, pattern)[0]


def test_randomized_breaks_the_symmetric_tie_that_blocks_the_basic_algorithm():
    """Sec. 6.4 / Fig. 14b: deterministic choices keep the symmetry (both followers pick the
    same axis slot forever); random choices break it and the pattern is formed."""
    basic = mirrored_pair_run(BasicAlgorithm(axis_tolerance=1e-6))
    randomized = mirrored_pair_run(RandomizedAlgorithm(axis_tolerance=1e-6))
    assert basic[-20:].min() > 40          # one slot stays empty: distance ~ 50 between slots
    assert randomized[-20:].max() < 2.0


def test_randomized_forms_a_non_lb_symmetric_pattern_up_to_reflection():
    """Sec. 6.4 steps 1-5: the followers agree on one placement; without chirality the
    pattern and its mirror image are indistinguishable, so it is formed up to reflection."""
    spec = robofleet.load_scenario(ASYM, overrides={"duration": 700})
    mirrored = 0
    for seed in (1, 2):
        r = robofleet.simulate(spec, seed=seed).results
        assert r["delta_m_final"] <= r["xi"], seed
        mirrored += r["formed_mirror_image"]
    assert mirrored >= 1   # evidence that reflection cannot be told apart without chirality


def test_basic_refuses_a_non_lb_symmetric_pattern_and_randomized_accepts_it():
    from robofleet.core.errors import ScenarioError
    with pytest.raises(ScenarioError, match="lb-symmetric"):
        robofleet.load_scenario(ASYM, overrides={"algorithm.kind": "basic"})
    with pytest.warns(UserWarning, match="lb-symmetric"):
        spec = robofleet.load_scenario(ASYM, overrides={"algorithm.kind": "basic", "checks.pattern": "warn", "duration": 5})
        robofleet.simulate(spec, seed=1)


def test_shared_chirality_forms_the_non_lb_symmetric_pattern_itself():
    """Sec. 6.2.3: with common chirality the pattern (not its mirror) is formed."""
    spec = robofleet.load_scenario("scenarios/flocking/chirality_asymmetric.yaml", overrides={"duration": 800})
    for seed in (1,):
        r = robofleet.simulate(spec, seed=seed).results
        assert r["delta_e_final"] <= r["xi"] and not r["formed_mirror_image"], seed


def test_shared_axes_form_a_pattern_with_several_points_on_the_axis():
    """Sec. 6.2.4: three slots on Y (refused by the basic algorithm, Fig. 7)."""
    from robofleet.core.errors import ScenarioError
    spec = robofleet.load_scenario("scenarios/flocking/shared_axes_column.yaml", overrides={"duration": 600})
    r = robofleet.simulate(spec, seed=2).results
    assert r["delta_e_final"] <= r["xi"]
    with pytest.raises(ScenarioError, match="at most 1 point"):  # at validation, which reads the pattern file
        robofleet.simulate(robofleet.load_scenario("scenarios/flocking/shared_axes_column.yaml", overrides={"algorithm.kind": "stripe"}), seed=1)


HEADING_OVERRIDES = {"duration": 500, "scheduler.kind": "fsync", "leader.turn_probability": 0.0, "followers.speed_min": 2.0}


@pytest.fixture(scope="module")
def basic_heading_runs():
    base = robofleet.load_scenario("scenarios/flocking/wedge_async.yaml", overrides=HEADING_OVERRIDES)
    return [robofleet.simulate(base, seed=s).results for s in (1, 2)]


@pytest.mark.parametrize("kind", ["observable_heading", "memory"])
def test_heading_knowledge_gives_the_directed_formation(kind, basic_heading_runs):
    """Sec. 6.1 / 6.3: with the leader's heading (observed or inferred from one stored
    position) the followers form the directed target: Δ_r ≤ ξ, which the basic algorithm
    does not reach on the same runs (it keeps a wrong-heading formation, Sec. 5.1)."""
    spec = robofleet.load_scenario("scenarios/flocking/wedge_async.yaml", overrides={**HEADING_OVERRIDES, "algorithm.kind": kind})
    for seed in (1, 2):
        r = robofleet.simulate(spec, seed=seed).results
        assert r["converged_r"] and r["delta_r_final"] <= r["xi"], seed
    assert all(x["converged_e"] for x in basic_heading_runs)
    assert not all(x["converged_r"] for x in basic_heading_runs)


def wrong_side_run(algorithm, duration=200):
    """Sec. 5.1, problem 2: the wedge formed in front of the leader, which drives straight at it."""
    from robofleet.flocking.metrics import delta_series, real_target
    pattern = patterns.wedge()
    starts = real_target(pattern, np.zeros(2), np.pi)              # the pattern turned round: in front
    course = LeaderCourse.build([0.0, 0.0], 0.0, 0.5, np.array([duration + 2.0]), np.array([0.0]))
    res = run(algorithm, pattern, LocalFrames.random(6, 3), starts, np.full(6, 2.0), course, SchedulerSpec(kind="fsync"),
              duration=duration, scheduler_rng=np.random.default_rng(0), algorithm_rng=np.random.default_rng(1))
    return delta_series(res.positions, res.headings, pattern)


def test_basic_keeps_a_wrong_heading_formation_that_the_observed_heading_avoids():
    """Sec. 5.1 problem 2 and Sec. 6.1: oblivious followers keep the mirrored-in-front
    formation while the leader drives straight at them; seeing the heading fixes it."""
    from robofleet.flocking.knowledge import ObservableHeadingAlgorithm
    de, dr = wrong_side_run(BasicAlgorithm())
    assert de.max() < 5.0 and dr.min() > 900.0          # formed, but facing the wrong way
    de_h, dr_h = wrong_side_run(ObservableHeadingAlgorithm())
    assert dr_h[-10:].max() < 5.0
