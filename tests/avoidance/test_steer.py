"""The compiled command toward the projected goal equals, bit for bit, the numpy
expressions of appendix C's one-step controller it replaces."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.avoidance.kernels import PARALLEL_MIN_ROBOTS
from robofleet.avoidance.projection import Projection, steer


def numpy_command(estimates, proj: Projection, v_max, dt, hold):
    """``u = min(v_max, ‖g* − p̂‖/Δt)·(g* − p̂)/‖g* − p̂‖`` written as array expressions."""
    target = np.where(proj.empty[:, None], estimates, proj.point)
    delta = target - estimates
    dist = np.linalg.norm(delta, axis=1)
    speed = np.minimum(v_max, dist / dt)
    u = np.where(dist[:, None] > 1e-12, delta * (speed / np.maximum(dist, 1e-300))[:, None], 0.0)
    u[hold] = 0.0
    return u, np.linalg.norm(u, axis=1), np.where(proj.empty, np.inf, dist)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("per_robot_limit", [False, True])
@pytest.mark.parametrize("n", [500, PARALLEL_MIN_ROBOTS + 500])  # the serial and the parallel kernel
def test_steer_is_the_numpy_command_bit_for_bit(seed, per_robot_limit, n):
    rng = np.random.default_rng(seed)
    estimates = rng.normal(size=(n, 2)) * 10 ** rng.uniform(-3, 3)
    point = estimates + rng.normal(size=(n, 2)) * 10.0 ** rng.integers(-14, 1, size=(n, 1))  # reaches down to under 1e-12
    same = rng.random(n) < 0.1
    point[same] = estimates[same]  # the goal already at the estimate
    empty = rng.random(n) < 0.15
    point[empty] = np.nan  # what the projection reports for an empty cell
    proj = Projection(point, empty, np.full((n, 2), -1, np.intp))
    v_max = rng.uniform(0.1, 2.0, n) if per_robot_limit else 0.4
    hold = rng.random(n) < 0.2
    got, expected = steer(estimates, proj, v_max, 0.1, hold), numpy_command(estimates, proj, v_max, 0.1, hold)
    for a, b in zip(got, expected):
        np.testing.assert_array_equal(a, b)
        assert np.array_equal(np.signbit(a), np.signbit(b))  # the same zeros too


def test_a_goal_at_the_estimate_gives_no_command():
    estimates = np.array([[1.0, 2.0], [0.0, 0.0]])
    proj = Projection(estimates.copy(), np.zeros(2, bool), np.full((2, 2), -1, np.intp))
    u, speed, move = steer(estimates, proj, 0.4, 0.1, np.zeros(2, bool))
    assert not u.any() and not speed.any() and not move.any()
