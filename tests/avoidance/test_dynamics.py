"""Robot models of paper 003: exact discretisations, saturation, appendix D quadrotor."""

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from robofleet.dynamics import double_integrator as di
from robofleet.dynamics import quadrotor as quad
from robofleet.dynamics import unicycle as uni

finite = st.floats(-2, 2, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(st.lists(finite, min_size=6, max_size=6), st.floats(0.01, 0.5))
def test_double_integrator_step_is_exact_constant_acceleration(values, dt):
    p, v, a = np.array(values[:2]), np.array(values[2:4]), np.array(values[4:]) * 0.2
    params = di.DoubleIntegratorParams(a_max=10.0, v_max=5.0)
    out = di.step(np.concatenate([p, v])[None], a[None], dt, params)[0]
    np.testing.assert_allclose(out[:2], p + v * dt + 0.5 * a * dt**2, atol=1e-12)
    np.testing.assert_allclose(out[2:], v + a * dt, atol=1e-12)


def test_double_integrator_saturates_acceleration_norm():
    params = di.DoubleIntegratorParams(a_max=1.0, v_max=5.0)
    out = di.step(np.zeros((1, 4)), np.array([[3.0, 4.0]]), 1.0, params)
    np.testing.assert_allclose(out[0, 2:], [0.6, 0.8])


def test_unicycle_rk2_matches_reference_integration():
    params = uni.UnicycleParams(v_max=1.0, omega_max=2.0)
    state = np.array([[0.3, -0.2, 0.7]])
    control = np.array([[0.8, 1.2]])
    dt = 0.1
    ref = solve_ivp(lambda t, s: [0.8 * np.cos(s[2]), 0.8 * np.sin(s[2]), 1.2], (0, dt), state[0], rtol=1e-12, atol=1e-12).y[:, -1]
    out = uni.step(state, control, dt, params)[0]
    assert np.linalg.norm(out - ref) < 1e-4  # RK2 local error O(dt³)
    assert np.linalg.norm(out - ref) > 0  # not an exact integrator: the check can fail


def test_unicycle_saturates_inputs():
    params = uni.UnicycleParams(v_max=0.5, omega_max=0.1)
    out = uni.step(np.zeros((1, 3)), np.array([[10.0, -10.0]]), 1.0, params)[0]
    assert np.isclose(out[2], -0.1)
    assert np.isclose(np.hypot(out[0], out[1]), 0.5, rtol=1e-3)


def test_quadrotor_defaults_are_appendix_d():
    p = quad.QuadrotorParams()
    assert (p.k_Dx, p.k_Dy, p.k_vz, p.tau_vz) == (0.25, 0.33, 1.2270, 0.3367)
    assert (p.k_phi, p.tau_phi, p.k_theta, p.tau_theta) == (1.1260, 0.2368, 1.1075, 0.2318)


def test_quadrotor_hover_is_an_equilibrium():
    state = np.zeros((2, 9))
    state[:, :3] = [[1, 2, 3], [0, 0, 1]]
    out = quad.step(state, quad.hover_control(2), 0.05, quad.QuadrotorParams())
    np.testing.assert_allclose(out, state)


def test_quadrotor_steady_state_follows_appendix_d():
    """Constant pitch command, yaw 0: v_x → g·tan(k_θ θ_c)/k_Dx; v_z → k_vz v_zc; ψ̇ = ψ̇_c."""
    params = quad.QuadrotorParams()
    state = np.zeros((1, 9))
    u = np.array([[0.0, 0.1, 0.4, 0.0]])
    for _ in range(1200):
        state = quad.step(state, u, 0.05, params)
    assert np.isclose(state[0, 3], 9.81 * np.tan(1.1075 * 0.1) / 0.25, rtol=1e-4)
    assert np.isclose(state[0, 5], 1.2270 * 0.4, rtol=1e-6)
    assert np.isclose(state[0, 7], 1.1075 * 0.1, rtol=1e-6)


def test_quadrotor_matches_reference_integration_with_yaw():
    params = quad.QuadrotorParams()
    x0 = np.array([0, 0, 1, 0.2, -0.1, 0, 0.05, -0.03, 0.4])
    u = np.array([0.1, -0.2, 0.3, 0.5])

    def rhs(t, x):
        return quad.derivative(list(x), list(u), params)

    ref = solve_ivp(rhs, (0, 0.05), x0, rtol=1e-12, atol=1e-12).y[:, -1]
    out = quad.step(x0[None], u[None], 0.05, params)[0]
    assert np.max(np.abs(out - ref)) < 1e-5  # RK4 local error O(dt⁵); Euler would be ~1e-3


@pytest.mark.parametrize("module,params,nx,nu", [
    (quad, quad.QuadrotorParams(), 9, 4),
    (uni, uni.UnicycleParams(v_max=1.0, omega_max=1.0), 3, 2),
])
def test_symbolic_step_equals_numeric_step(module, params, nx, nu):
    rng = np.random.default_rng(3)
    x, u = rng.uniform(-0.3, 0.3, nx), rng.uniform(-0.3, 0.3, nu)
    X, U = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    f = ca.Function("f", [X, U], [module.symbolic_step(X, U, 0.05, params)])
    np.testing.assert_allclose(np.array(f(x, u)).ravel(), module.step(x[None], u[None], 0.05, params)[0], atol=1e-12)


def test_model_parameters_are_validated():
    with pytest.raises(ValueError):
        di.DoubleIntegratorParams(v_max=1.0)  # a_max missing
    with pytest.raises(ValueError):
        uni.UnicycleParams(v_max=-1.0, omega_max=1.0)
    with pytest.raises(ValueError):
        quad.QuadrotorParams(k_Dz=1.0)  # unknown key


def test_quadrotor_braking_control_stops_a_moving_quadrotor():
    params = quad.QuadrotorParams()
    state = np.zeros((2, 9))
    state[:, 3:5] = [[1.0, -0.5], [-0.8, 0.3]]
    state[:, 8] = [0.0, 1.2]  # one with yaw
    for _ in range(200):
        state = quad.step(state, quad.braking_control(state, params), 0.05, params)
    assert np.all(np.abs(state[:, 3:6]) < 1e-2)
