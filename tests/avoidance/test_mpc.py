"""B-UAVC MPC: every predicted and every realised position stays in the cell."""

import numpy as np
import pytest

from robofleet.avoidance.cell3d import project_onto_polytope, workspace_box_planes
from robofleet.avoidance.mpc import (
    BuavcMPC,
    MPCConfig,
    SingleIntegratorParams,
)
from robofleet.avoidance.navigation.recovery import rotate_goal_clockwise
from robofleet.core.errors import ConfigError
from robofleet.dynamics import double_integrator as di
from robofleet.dynamics import quadrotor as quad
from robofleet.dynamics import unicycle as uni


def corner_cell(dim):
    """A box cut by a slanted plane; the goal (3, 3[, 2]) lies outside it."""
    lo, hi = [-1.0] * dim, [1.0] * dim
    if dim == 3:
        lo[2], hi[2] = 0.0, 2.5
    A, b = workspace_box_planes(lo, hi)
    slant = np.zeros(dim)
    slant[:2] = [0.6, 0.8]
    return np.vstack([A, slant]), np.append(b, 0.5)


CASES = [
    ("single_integrator", SingleIntegratorParams(v_max=0.4), 2, 0.1, 10, lambda s, u, dt, p: s + u * dt, np.zeros(2)),
    ("double_integrator", di.DoubleIntegratorParams(a_max=1.0, v_max=0.5), 2, 0.1, 10, di.step, np.array([0.0, 0.0, 0.3, -0.2])),
    ("unicycle", uni.UnicycleParams(v_max=0.8, omega_max=np.pi / 2), 2, 0.1, 10, uni.step, np.array([0.0, 0.0, 2.0])),
    ("quadrotor", quad.QuadrotorParams(), 3, 0.05, 20, quad.step, np.array([0, 0, 1.0, 0.2, 0, 0, 0, 0, 0.3])),
]


SOLVER_CASES = [(*case, "ipopt") for case in CASES] + [(*case, "rti") for case in CASES if case[0] in ("unicycle", "quadrotor")]


@pytest.mark.parametrize("name,params,dim,dt,horizon,step,x0,solver", SOLVER_CASES, ids=[f"{c[0]}-{c[-1]}" for c in SOLVER_CASES])
def test_mpc_keeps_every_stage_in_the_cell(name, params, dim, dt, horizon, step, x0, solver):
    A, b = corner_cell(dim)
    config = MPCConfig(horizon=horizon, deadlock_progress=0.01, solver=solver)
    mpc = BuavcMPC(name, params, dim=dim, dt=dt, config=config, n_robots=1)
    goal = np.full((1, dim), 3.0)
    if dim == 3:
        goal[0, 2] = 2.0
    state = x0[None].copy()
    target, _ = project_onto_polytope(goal, A[None], b[None])
    closest = np.inf
    valid = np.ones((1, len(b)), bool)
    for _ in range(round(4.0 / dt)):
        u, info = mpc.control(state, goal, A[None], b[None], valid)
        assert not info["fallback"][0], "the solver failed on a feasible problem"
        plan = info["plans"][0]
        assert np.all(plan[1:] @ A.T <= b + 1e-6)
        np.testing.assert_allclose(plan[0], state[0, :dim], atol=1e-6)
        state = step(state, u, dt, params)
        assert np.all(state[0, :dim] @ A.T <= b + 1e-5)  # the realised motion too
        closest = min(closest, np.linalg.norm(state[0, :dim] - target[0]))
    # it reaches the point of the cell nearest to the goal (a corner; the unicycle, which must
    # approach it with a suitable heading, within the 0.2 m goal tolerance of the paper's setup)
    assert closest < (0.2 if name == "unicycle" else 0.05)


def test_mpc_falls_back_when_the_cell_is_unreachable():
    """The robot starts far outside its cell: no plan exists; the safe fallback (zero) is used."""
    mpc = BuavcMPC("single_integrator", SingleIntegratorParams(v_max=0.4), dim=2, dt=0.1, config=MPCConfig(horizon=5), n_robots=1)
    A, b = workspace_box_planes([-1, -1], [1, 1])
    u, info = mpc.control(np.array([[5.0, 5.0]]), np.zeros((1, 2)), A[None], b[None], np.ones((1, 4), bool))
    assert info["fallback"][0]
    np.testing.assert_allclose(u, 0.0)


def test_double_integrator_fallback_brakes():
    params = di.DoubleIntegratorParams(a_max=1.0, v_max=2.0)
    mpc = BuavcMPC("double_integrator", params, dim=2, dt=0.1, config=MPCConfig(horizon=5), n_robots=1)
    A, b = workspace_box_planes([-1, -1], [1, 1])
    u, info = mpc.control(np.array([[5.0, 5.0, 1.0, 0.0]]), np.zeros((1, 2)), A[None], b[None], np.ones((1, 4), bool))
    assert info["fallback"][0]
    np.testing.assert_allclose(u, [[-1.0, 0.0]])


def test_more_cell_rows_than_the_problem_holds_keeps_the_tightest():
    mpc = BuavcMPC("single_integrator", SingleIntegratorParams(v_max=0.4), dim=2, dt=0.1, config=MPCConfig(horizon=5, max_constraints=4), n_robots=1)
    ang = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    A = np.stack([np.cos(ang), np.sin(ang)], -1)
    b = np.arange(1.0, 13.0)
    _, bp = mpc.cell_parameters(A, b, np.ones(12, bool), np.zeros(2))
    np.testing.assert_allclose(bp, [1, 2, 3, 4])


def test_goal_rotation_is_clockwise_about_the_robot():
    g = rotate_goal_clockwise(np.array([[1.0, 1.0, 2.0]]), np.array([[1.0, 3.0, 2.0]]))
    np.testing.assert_allclose(g, [[3.0, 1.0, 2.0]])


def test_deadlocked_robot_rotates_its_goal():
    """A robot pinned against a face perpendicular to its goal direction gets a rotated goal."""
    cfg = MPCConfig(horizon=5, deadlock_steps=5, deadlock_progress=0.01, recover_steps=3)
    mpc = BuavcMPC("single_integrator", SingleIntegratorParams(v_max=0.4), dim=2, dt=0.1, config=cfg, n_robots=1)
    A, b = workspace_box_planes([-1, -1], [0, 1])
    state = np.array([[0.0, 0.0]])
    goal = np.array([[3.0, 0.0]])
    rotated = False
    for _ in range(20):
        u, info = mpc.control(state, goal, A[None], b[None], np.ones((1, 4), bool))
        rotated |= not np.allclose(info["goals"], goal)
        state = state + u * 0.1
    assert rotated and mpc.deadlocks[0] >= 1


def test_bad_mpc_input_is_rejected():
    with pytest.raises(ValueError, match="horizon"):
        MPCConfig(horizon=0)
    with pytest.raises(ConfigError, match="model"):
        BuavcMPC("hovercraft", None, dim=2, dt=0.1, config=MPCConfig(), n_robots=1)


def test_rollout_matches_the_simulator_step():
    params = quad.QuadrotorParams()
    mpc = BuavcMPC("quadrotor", params, dim=3, dt=0.05, config=MPCConfig(horizon=6), n_robots=1)
    rng = np.random.default_rng(0)
    U = rng.uniform(-0.3, 0.3, (6, 4))
    x = np.array([0, 0, 1.0, 0.1, -0.2, 0, 0.02, 0.01, 0.5])
    states = [x[None]]
    for u in U:
        states.append(quad.step(states[-1], u[None], 0.05, params))
    np.testing.assert_allclose(mpc.rollout(x, U), np.concatenate(states), atol=1e-12)
