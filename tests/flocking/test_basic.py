"""Algorithm 1 (Sec. 4): slot assignment, footnote 3, frame independence (Sec. 4.1)."""

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from robofleet.flocking import metrics, patterns
from robofleet.flocking.basic import BasicAlgorithm
from robofleet.flocking.hula_hoop import HulaHoopAlgorithm
from robofleet.flocking.knowledge import ChiralityAlgorithm
from robofleet.flocking.model import LocalFrames, Snapshot, look
from robofleet.flocking.randomized import RandomizedAlgorithm
from robofleet.flocking.stripe import StripeAlgorithm

from .helpers import world_decisions

LB_PATTERNS = [patterns.wedge(), patterns.line(), patterns.spread(), patterns.random_lb_symmetric(5, 11), patterns.random_lb_symmetric(8, 12)]
ASYMMETRIC = patterns.validate_points([[-60.0, 40.0], [-90.0, -10.0], [-140.0, 70.0], [-40.0, -80.0]], name="asym")
DETERMINISTIC = [BasicAlgorithm(), StripeAlgorithm(), HulaHoopAlgorithm(), RandomizedAlgorithm()]


def generic(pattern, leader, followers, margin=1e-3, axis_margin=1.0):
    """True when no follower is near Y (S_0 tolerance 0.5) and no two followers nearly tie in a sort key."""
    b = followers.mean(axis=0)
    u = leader - b
    if np.linalg.norm(u) < 1.0:
        return False
    u = u / np.linalg.norm(u)
    lat = (followers - leader) @ np.array([-u[1], u[0]])
    keys = [np.linalg.norm(followers - leader, axis=1), np.abs(lat)]
    gaps = [np.abs(k[:, None] - k[None]) + np.eye(len(k)) * 1e9 for k in keys]
    return bool(np.abs(lat).min() > axis_margin and min(g.min() for g in gaps) > margin)


config = st.tuples(st.integers(0, len(LB_PATTERNS) - 1), st.integers(0, 2**32 - 1),
                   st.floats(-np.pi, np.pi), st.floats(-np.pi, np.pi), st.integers(0, 3))


@settings(max_examples=80, deadline=None)
@given(config)
def test_destination_independent_of_local_frame(cfg):
    """Sec. 4.1: rotation and reflection of the local frame do not change the world
    destination for lb-symmetric patterns (all deterministic Sec. 4-5 algorithms)."""
    p_idx, seed, a1, a2, alg_idx = cfg
    pattern = LB_PATTERNS[p_idx]
    rng = np.random.default_rng(seed)
    followers = rng.uniform(0, 512, (pattern.size, 2))
    leader = rng.uniform(0, 512, 2)
    assume(generic(pattern, leader, followers))
    algorithm = DETERMINISTIC[alg_idx]
    i = int(rng.integers(pattern.size))
    outs = []
    for angle, hand in ((a1, 1.0), (a2, 1.0), (a2, -1.0), (a1, -1.0)):
        frames = LocalFrames(np.full(pattern.size, angle), np.full(pattern.size, hand))
        d = algorithm.decide(look(frames, i, leader, followers), pattern, np.random.default_rng(0))
        outs.append(frames.to_world(i, d.path, followers[i]))
    for o in outs[1:]:
        assert o.shape == outs[0].shape
        assert np.allclose(o, outs[0], atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-np.pi, np.pi), st.floats(-np.pi, np.pi))
def test_rotation_invariance_holds_for_any_pattern_but_reflection_does_not(seed, a1, a2):
    """Fig. 6: with a non-lb-symmetric pattern the destination depends on chirality only."""
    rng = np.random.default_rng(seed)
    followers = rng.uniform(0, 512, (ASYMMETRIC.size, 2))
    leader = rng.uniform(0, 512, 2)
    assume(generic(ASYMMETRIC, leader, followers))
    alg = BasicAlgorithm()
    d = {}
    for key, angle, hand in (("a", a1, 1.0), ("b", a2, 1.0), ("m", a1, -1.0)):
        frames = LocalFrames(np.full(ASYMMETRIC.size, angle), np.full(ASYMMETRIC.size, hand))
        d[key] = [frames.to_world(i, alg.decide(look(frames, i, leader, followers), ASYMMETRIC).destination, followers[i]) for i in range(ASYMMETRIC.size)]
    assert np.allclose(d["a"], d["b"], atol=1e-6)
    assert not np.allclose(d["a"], d["m"], atol=1e-3)  # the mirrored frame forms the mirrored pattern


@pytest.mark.parametrize("algorithm", [BasicAlgorithm(), StripeAlgorithm(), HulaHoopAlgorithm(), ChiralityAlgorithm()])
def test_followers_choose_distinct_slots_covering_the_target(algorithm):
    """Lines 15-38: in generic configurations the oblivious choices form a bijection onto
    the slots of the estimated target, whatever the frames."""
    for seed in range(60):
        rng = np.random.default_rng(seed)
        pattern = [*LB_PATTERNS, patterns.random_lb_symmetric(None, rng)][seed % 6]
        followers = rng.uniform(0, 512, (pattern.size, 2))
        leader = rng.uniform(0, 512, 2)
        frames = LocalFrames.random(pattern.size, rng, algorithm.frames)
        if not generic(pattern, leader, followers):
            continue  # a robot in S_0 beyond the axis slots: the listing's |S_0| > |F_0| case
        paths, _ = world_decisions(algorithm, pattern, leader, followers, frames)
        target = metrics.estimated_target(pattern, leader, followers)
        dests = np.array([p[-1] for p in paths])
        gap = np.linalg.norm(dests[:, None] - target[None], axis=-1)
        if isinstance(algorithm, (StripeAlgorithm, HulaHoopAlgorithm)):
            continue  # moves are cut at the stable space; slots are checked below
        assert np.all(gap.min(axis=1) < 1e-6), seed
        assert sorted(gap.argmin(axis=1)) == list(range(pattern.size)), seed


@pytest.mark.parametrize("algorithm", [StripeAlgorithm(), HulaHoopAlgorithm()])
def test_variant_slot_choices_are_a_bijection(algorithm):
    for seed in range(40):
        rng = np.random.default_rng(seed)
        pattern = LB_PATTERNS[seed % 5]
        followers = rng.uniform(0, 512, (pattern.size, 2))
        leader = rng.uniform(0, 512, 2)
        frames = LocalFrames(np.zeros(pattern.size), np.ones(pattern.size))  # one chirality: slot ids comparable
        if not generic(pattern, leader, followers):
            continue
        _, slots = world_decisions(algorithm, pattern, leader, followers, frames)
        assert sorted(slots) == list(range(pattern.size)), seed


def test_footnote_3_waits_when_leader_is_on_the_barycenter():
    snap = Snapshot(leader=np.array([5.0, 0.0]), others=np.array([[10.0, 0.0]]))
    d = BasicAlgorithm().decide(snap, patterns.validate_points([[-10.0, 5.0], [-10.0, -5.0]]))
    assert d.slot == -1 and np.allclose(d.destination, 0.0)


def test_sorting_rule_farthest_robot_takes_farthest_slot():
    """Lines 12-19: the k-th farthest robot of S_1 goes to the k-th farthest slot of F_1."""
    pattern = patterns.validate_points([[-100.0, 50.0], [-100.0, -50.0], [-40.0, 20.0], [-40.0, -20.0]])
    leader = np.array([0.0, 0.0])
    # all followers behind the leader (B on -x, Y = +x); two on each side
    followers = np.array([[-200.0, 30.0], [-50.0, 10.0], [-200.0, -30.0], [-50.0, -10.0]])
    frames = LocalFrames(np.zeros(4), np.ones(4))
    paths, slots = world_decisions(BasicAlgorithm(), pattern, leader, followers, frames)
    dest = np.array([p[-1] for p in paths])
    target = metrics.estimated_target(pattern, leader, followers)
    assert np.allclose(dest, target[[0, 2, 1, 3]])  # far robots -> far slots, near -> near


def test_h_set_sends_the_extra_robot_to_the_axis_slot():
    """Lines 20-26: with |S_1| = |F_1| + 1 the extra (lowest-ranked) robot of S_1 takes F_0."""
    pattern = patterns.validate_points([[-100.0, 40.0], [-100.0, -40.0], [-60.0, 0.0]])
    leader = np.array([0.0, 0.0])
    followers = np.array([[-150.0, 30.0], [-70.0, 15.0], [-120.0, -50.0]])
    frames = LocalFrames(np.zeros(3), np.ones(3))
    paths, slots = world_decisions(BasicAlgorithm(), pattern, leader, followers, frames)
    assert slots[1] == 2            # the nearer left robot: rank 2 > |F_1| = 1 -> the axis slot
    assert sorted(slots) == [0, 1, 2]


def test_s0_robot_beyond_axis_slots_goes_to_the_smaller_side():
    """Lines 31-38: a robot on Y ranked beyond |F_0| moves to F_1 or F_2 (the side with fewer robots)."""
    pattern = patterns.validate_points([[-100.0, 40.0], [-100.0, -40.0], [-60.0, 0.0]])
    leader = np.array([0.0, 0.0])
    # B lies on the x axis; robots 0 and 1 on Y; robot 2 on the right (y < 0)
    followers = np.array([[-150.0, 0.0], [-30.0, 0.0], [-120.0, 0.0]])
    followers[2] = [-120.0, -1e-3]
    followers[0] = [-150.0, 1e-3]
    frames = LocalFrames(np.zeros(3), np.ones(3))
    alg = BasicAlgorithm(axis_tolerance=0.1)
    paths, slots = world_decisions(alg, pattern, leader, followers, frames)
    assert slots[0] == 2                       # farthest on Y takes the axis slot (k = 1 <= |F_0|)
    # second on Y: |S_1| = 0 <= |S_2| = 0 -> F_1; line 36's index |F_1| - |S_1| + (k - |F_0|) = 2
    # exceeds |F_1| = 1 and is clamped (module docstring of basic.py)
    assert slots[1] == 0
