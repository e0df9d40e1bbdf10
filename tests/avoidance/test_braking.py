"""The double-integrator braking rule keeps the robot inside its cell (our rule, braking.py)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robofleet.avoidance.braking import braking_control, braking_rule, stopping_distance, stopping_point
from robofleet.avoidance.cell3d import project_onto_polytope
from robofleet.dynamics import double_integrator as di


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 3.0), st.floats(0.2, 3.0), st.sampled_from([0.05, 0.1, 0.2]))
def test_stopping_distance_is_what_the_braking_policy_travels(speed, a_max, dt):
    params = di.DoubleIntegratorParams(a_max=a_max, v_max=10.0)
    x = np.array([[0.0, 0.0, speed, 0.0]])
    for _ in range(int(speed / (a_max * dt)) + 3):
        x = di.step(x, braking_control(x[:, 2:], a_max, dt), dt, params)
    assert abs(x[0, 2]) < 1e-12
    assert np.isclose(x[0, 0], stopping_distance(speed, a_max, dt), atol=1e-12)


def random_cell(rng, m):
    """A random polygon cell {A p ≤ b} containing a disc of radius 0.5 around the origin."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, m))
    A = np.stack([np.cos(angles), np.sin(angles)], -1)
    b = rng.uniform(0.5, 2.0, m)
    return A, b


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(3, 8), st.floats(0.3, 2.0), st.floats(0.2, 1.5))
def test_braking_rule_never_leaves_a_fixed_cell(seed, m, a_max, v_max):
    """Invariant: the braking segment starts in the cell ⇒ all positions, sampled within
    every step, stay in the cell for any goal (also goals far outside)."""
    rng = np.random.default_rng(seed)
    A, b = random_cell(rng, m)
    params = di.DoubleIntegratorParams(a_max=a_max, v_max=v_max)
    dt = 0.1
    n = 16
    p = rng.uniform(-0.3, 0.3, (n, 2))
    v = rng.normal(size=(n, 2)) * 0.3
    v *= np.minimum(1.0, v_max / np.linalg.norm(v, axis=1, keepdims=True))
    A_n, b_n, valid = np.repeat(A[None], n, 0), np.repeat(b[None], n, 0), np.ones((n, m), bool)
    start_ok = np.all(stopping_point(p, v, a_max, dt) @ A.T <= b, axis=1)
    p, v = p[start_ok], v[start_ok]
    A_n, b_n, valid = A_n[start_ok], b_n[start_ok], valid[start_ok]
    goals = rng.uniform(-6, 6, (len(p), 2))
    state = np.concatenate([p, v], axis=1)
    tau = np.linspace(0, dt, 6)[1:]
    for _ in range(60):
        target, _ = project_onto_polytope(goals, A_n, b_n, valid)
        u, _ = braking_rule(state[:, :2], state[:, 2:], target, A_n, b_n, valid, params, dt)
        pos, vel = state[:, :2], state[:, 2:]
        inner = pos[:, None] + vel[:, None] * tau[None, :, None] + 0.5 * u[:, None] * tau[None, :, None] ** 2
        assert np.all(inner @ A.T <= b + 1e-8)
        state = di.step(state, u, dt, params)
        assert np.all(np.linalg.norm(state[:, 2:], axis=1) <= v_max + 1e-9)


def test_braking_rule_reaches_a_goal_inside_the_cell():
    A = np.array([[[1.0, 0], [-1, 0], [0, 1], [0, -1]]])
    b = np.array([[2.0, 2, 2, 2]])
    params = di.DoubleIntegratorParams(a_max=1.0, v_max=0.8)
    state = np.array([[-1.5, -1.5, 0.0, 0.0]])
    goal = np.array([[1.2, 0.7]])
    for _ in range(200):
        u, _ = braking_rule(state[:, :2], state[:, 2:], goal, A, b, np.ones((1, 4), bool), params, 0.1)
        state = di.step(state, u, 0.1, params)
    assert np.linalg.norm(state[0, :2] - goal[0]) < 1e-3
    assert np.linalg.norm(state[0, 2:]) < 1e-3


def test_without_the_rule_the_same_robot_would_leave_the_cell():
    """Sanity check that the invariant test can fail: pure tracking overshoots a wall."""
    from robofleet.avoidance.braking import tracking_control

    params = di.DoubleIntegratorParams(a_max=0.5, v_max=1.0)
    state = np.array([[0.0, 0.0, 1.0, 0.0]])
    target = np.array([[0.5, 0.0]])  # wall at x = 0.5, arriving at full speed
    xs = []
    for _ in range(40):
        state = di.step(state, tracking_control(state[:, :2], state[:, 2:], target, params, 0.1), 0.1, params)
        xs.append(state[0, 0])
    assert max(xs) > 0.5 + 1e-3
