"""Braking-safe RTI for the quadrotor MPC (issue 10): every applied in-cell plan stays in
the cell, respects the speed limit and ends at rest; the shifted plan continued by the
zero input stays in the cell; an estimate outside its cell gets a plan that re-enters it;
the QP only drops rows no admissible increment can reach."""

import numpy as np
import pytest

from robofleet.avoidance.cell3d import workspace_box_planes
from robofleet.avoidance.mpc import BuavcMPC, MPCConfig
from robofleet.avoidance.rti import CondensedSQP, rows_in_reach
from robofleet.core.errors import ConfigError
from robofleet.dynamics import quadrotor as quad

DT, N, V_MAX = 0.05, 20, 1.0
PARAMS = quad.QuadrotorParams()


def quadrotor_mpc(**config) -> BuavcMPC:
    return BuavcMPC("quadrotor", PARAMS, dim=3, dt=DT, config=MPCConfig(horizon=N, deadlock_progress=0.01, **config),
                    n_robots=1, speed_limit=V_MAX)


def box_cell(lo=(-1.0, -1.0, 0.0), hi=(1.0, 1.0, 2.5)):
    A, b = workspace_box_planes(list(lo), list(hi))
    return A, b


def test_applied_plans_stay_in_the_cell_within_the_speed_limit_and_end_at_rest():
    """Flying at a goal beyond a 2 m box from rest: every plan is in the cell (exact rollout),
    below v_max, and ends (nearly) at rest and level; the realised motion stays in the cell."""
    mpc = quadrotor_mpc()
    A, b = box_cell()
    goal = np.array([5.0, 4.0, 2.0])
    state = np.array([-0.8, -0.8, 1.0, 0, 0, 0, 0, 0, 0.3])
    fastest = 0.0
    for _ in range(40):
        result = mpc.plan(0, state, goal, A, b)
        assert result.in_cell
        X = mpc.rollout(state, result.inputs)
        np.testing.assert_allclose(X[:, :3], result.positions)
        assert np.all(X[1:, :3] @ A.T <= b + 1e-9)
        assert np.all(np.linalg.norm(X[1:, 3:5], axis=1) <= V_MAX + 1e-3)
        assert np.all(np.abs(X[-1, 3:8]) <= 0.05), X[-1, 3:8]  # v_N, φ_N, θ_N ≈ 0
        fastest = max(fastest, float(np.linalg.norm(state[3:5])))
        state = quad.step(state[None], result.control[None], DT, PARAMS)[0]
        assert np.all(state[:3] @ A.T <= b + 1e-9)
    assert fastest > 0.5  # it did fly toward the goal, not hover


def test_shifted_plan_continued_by_zero_stays_in_the_cell():
    """The terminal rest set: from the state the first input reaches, the previous plan
    shifted by one step and extended by the zero input stays in the same cell (up to the
    drift the rest tolerance allows in one step)."""
    mpc = quadrotor_mpc()
    A, b = box_cell()
    goal = np.array([3.0, 3.0, 2.0])
    state = np.array([0.0, 0.0, 1.0, 0.6, 0.3, 0.0, 0.05, 0.05, 0.0])
    for _ in range(25):
        result = mpc.plan(0, state, goal, A, b)
        assert result.in_cell
        state = quad.step(state[None], result.control[None], DT, PARAMS)[0]
        continued = np.vstack([result.inputs[1:], np.zeros((1, 4))])
        X = mpc.rollout(state, continued)
        assert np.all(X[1:, :3] @ A.T <= b + 0.05 * DT)


def test_estimate_outside_its_cell_gets_a_plan_back_into_it():
    """An estimate 5 cm beyond a face, moving outward: no in-cell plan exists (p_1 is fixed
    by the velocity), so the least-violating plan is applied — not braking — and in closed
    loop the robot re-enters the cell and plans in it again."""
    mpc = quadrotor_mpc()
    A, b = box_cell()
    state = np.array([[1.05, 0.0, 1.0, 0.3, 0, 0, 0, 0, 0]])
    goal = np.array([[3.0, 0.0, 1.0]])  # beyond the face: the cost pulls outward
    u, info = mpc.control(state, goal, A[None], b[None], np.ones((1, len(b)), bool))
    assert info["fallback"][0] and info["recovery"][0]
    assert np.isnan(info["plans"][0]).all()  # 'plans' holds in-cell plans only
    first_violation = float(np.max(state[0, :3] @ A.T - b))
    solved_again = None
    for k in range(40):
        if k:
            u, info = mpc.control(state, goal, A[None], b[None], np.ones((1, len(b)), bool))
        if not info["fallback"][0]:
            solved_again = k
            break
        state = quad.step(state, u, DT, PARAMS)
    assert solved_again is not None, "never got back into its cell"
    assert np.max(state[0, :3] @ A.T - b) < first_violation


def test_ipopt_falls_back_on_the_same_recovery():
    """The 'ipopt' solver, which finds no plan for an estimate outside its cell, applies the
    SQP's least-violating plan instead of braking."""
    mpc = quadrotor_mpc(solver="ipopt")
    A, b = box_cell()
    state = np.array([[1.05, 0.0, 1.0, 0.3, 0, 0, 0, 0, 0]])
    u, info = mpc.control(state, np.array([[0.0, 0.0, 1.0]]), A[None], b[None], np.ones((1, len(b)), bool))
    assert info["fallback"][0] and info["recovery"][0]
    assert not np.allclose(u, quad.braking_control(state, PARAMS))


@pytest.mark.parametrize("seed", range(3))
def test_dropped_rows_hold_for_every_admissible_increment(seed):
    """The rows the QP leaves out are satisfied by the linearized positions for every δ in
    the input box, so dropping them cannot change the QP's solution."""
    rng = np.random.default_rng(seed)
    lo, hi = PARAMS.control_bounds()
    sqp = CondensedSQP(lambda x, u: quad.symbolic_step(x, u, DT, PARAMS), nx=9, nu=4, dim=3, horizon=8, u_lo=lo, u_hi=hi,
                       input_weight=1e-3)
    state = np.array([0.0, 0.0, 1.0, 0.5, -0.2, 0.1, 0.05, -0.02, 0.3])
    u = rng.uniform(sqp.u_lo, sqp.u_hi)
    A = rng.normal(size=(10, 3))
    A /= np.linalg.norm(A, axis=1, keepdims=True)
    b = rng.uniform(0.02, 0.6, 10)
    values, J = (np.asarray(v) for v in sqp._linearize(state, u))
    P, Jp = values.ravel()[:24].reshape(8, 3), J[:24].reshape(8, 3, -1)
    sens, upper = np.einsum("md,kdn->kmn", A, Jp), b[None, :] - P @ A.T
    width = np.maximum(sqp.u_hi - u, u - sqp.u_lo)
    kept = rows_in_reach(sens, upper, width)
    assert kept.any() and not kept.all()
    rows, _ = sqp._cell_rows(P, Jp, A, b, np.zeros(8), width)
    assert len(rows) == kept.sum()
    corners = np.where(rng.random((500, 32)) < 0.5, sqp.u_lo - u, sqp.u_hi - u)  # the box's vertices, where rows are tightest
    inside = rng.uniform(sqp.u_lo - u, sqp.u_hi - u, (500, 32))
    for delta in np.vstack([corners, inside]):
        moved = np.einsum("kmn,n->km", sens, delta)
        assert np.all(moved[~kept] <= upper[~kept] + 1e-12)


def test_rti_without_daqp_names_the_extra(monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_daqp(name, *args, **kwargs):
        if name == "daqp":
            raise ImportError("No module named 'daqp'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_daqp)
    with pytest.raises(ConfigError, match=r"mpc\.solver: 'rti' expected an installed daqp .*robofleet\[mpc\]"):
        quadrotor_mpc()


def test_an_arrived_robot_still_keeps_to_its_cell():
    """A quadrotor that has arrived, hovering 5 cm beyond a face of a cell that moved, is not
    left to brake: it flies back into the cell (and its step is not a counted fallback)."""
    mpc = quadrotor_mpc()
    A, b = box_cell()
    state = np.array([[1.05, 0.0, 1.0, 0, 0, 0, 0, 0, 0]])
    goal = state[:, :3].copy()
    arrived = np.array([True])
    for _ in range(30):
        u, info = mpc.control(state, goal, A[None], b[None], np.ones((1, len(b)), bool), arrived=arrived)
        assert not info["fallback"][0]
        state = quad.step(state, u, DT, PARAMS)
    assert np.all(state[0, :3] @ A.T <= b)
