"""Metrics of Def. 3.1-3.4 and Sec. 4.2 against brute force and hand-made cases."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from robofleet.core.errors import ConfigError
from robofleet.flocking import metrics, patterns

coords = st.floats(-100, 100, allow_nan=False, allow_infinity=False)


def brute_force_d(c, g):
    best = np.inf
    for perm in itertools.permutations(range(len(g))):
        best = min(best, np.linalg.norm(c - g[list(perm)], axis=1).sum())
    return best


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 7).flatmap(lambda n: st.tuples(arrays(float, (n, 2), elements=coords), arrays(float, (n, 2), elements=coords))))
def test_d_distance_equals_brute_force_over_permutations(cg):
    c, g = cg
    d = metrics.d_distance(c, g)
    assert d.value == pytest.approx(brute_force_d(c, g), rel=1e-9, abs=1e-9)
    # rho_i are the distances under the optimal matching and sum to D
    assert np.allclose(d.rho, np.linalg.norm(c - g[d.assignment], axis=1))
    assert d.rho.sum() == pytest.approx(d.value)
    assert sorted(d.assignment) == list(range(len(c)))


def test_d_distance_rejects_bad_shapes():
    with pytest.raises(ConfigError):
        metrics.d_distance(np.zeros((3, 2)), np.zeros((2, 2)))
    with pytest.raises(ConfigError):
        metrics.d_distance(np.zeros((3, 3)), np.zeros((3, 3)))


def test_delta_e_is_zero_on_the_estimated_target_and_delta_r_on_the_real_one():
    pat = patterns.wedge()
    leader = np.array([10.0, -4.0])
    heading = 0.7
    real = metrics.real_target(pat, leader, heading)
    positions = np.concatenate([leader[None], real])[None]
    de, dr = metrics.delta_series(positions, np.array([heading]), pat)
    assert dr[0] == pytest.approx(0.0, abs=1e-9)
    # a directed pattern formed along the heading is also its own estimated target
    assert de[0] == pytest.approx(0.0, abs=1e-9)
    # the same formation in front of the leader (rotated by pi): Delta_e = 0, Delta_r > 0
    wrong = metrics.real_target(pat, leader, heading + np.pi)
    de, dr = metrics.delta_series(np.concatenate([leader[None], wrong])[None], np.array([heading]), pat)
    assert de[0] == pytest.approx(0.0, abs=1e-9)
    assert dr[0] > 100


def test_estimated_target_matches_delta_series():
    rng = np.random.default_rng(3)
    pat = patterns.spread()
    pos = rng.uniform(0, 512, (4, pat.size + 1, 2))
    de, _ = metrics.delta_series(pos, np.zeros(4), pat)
    for t in range(4):
        target = metrics.estimated_target(pat, pos[t, 0], pos[t, 1:])
        assert de[t] == pytest.approx(metrics.d_distance(pos[t, 1:], target).value)
        # B_P lands on the line through L and B, on B's side
        b = pos[t, 1:].mean(axis=0)
        tb = target.mean(axis=0)
        u, v = b - pos[t, 0], tb - pos[t, 0]
        assert abs(u[0] * v[1] - u[1] * v[0]) < 1e-6 * np.linalg.norm(u) * np.linalg.norm(v)
        assert u @ v > 0


def test_convergence_time_needs_staying_below_xi():
    t = np.arange(6.0)
    assert metrics.convergence_time(t, np.array([9, 1, 9, 1, 1, 1.0]), 2.0) == 3.0
    assert np.isnan(metrics.convergence_time(t, np.array([1, 1, 1, 1, 1, 9.0]), 2.0))


def test_slot_changes_counts_per_follower_and_ignores_waits():
    robots = np.array([0, 1, 0, 1, 0, 0, 1])
    slots = np.array([2, 1, 3, -1, 3, 2, 1])
    assert metrics.slot_changes(robots, slots, 3).tolist() == [2, 0, 0]
