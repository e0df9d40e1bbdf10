"""ORCA (van den Berg et al. 2011): reciprocal half-planes and the 2-D velocity program."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from robofleet.avoidance.orca import OrcaParams, orca_halfplanes, orca_velocities, preferred_velocities, solve_velocity_lp


def min_distance_over_horizon(rel_pos, rel_vel, tau):
    """Analytic minimum of ‖p + t w‖ over t ∈ [0, τ]."""
    w2 = rel_vel @ rel_vel
    t = 0.0 if w2 == 0 else np.clip(-(rel_pos @ rel_vel) / w2, 0.0, tau)
    return np.linalg.norm(rel_pos + t * rel_vel)


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.5, 4.0), st.floats(0.1, 0.5))
def test_two_agent_velocities_are_collision_free_for_the_horizon(seed, tau, radius):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-3, 3, (2, 2))
    if np.linalg.norm(pos[0] - pos[1]) <= 2 * radius + 1e-6:
        pos[1] = pos[0] + 3 * radius * np.array([1.0, 0.0])
    vel = rng.uniform(-1, 1, (2, 2))
    pref = rng.uniform(-1.5, 1.5, (2, 2))
    params = OrcaParams(neighbor_dist=20.0, max_neighbors=5, time_horizon=tau)
    new, fallback = orca_velocities(pos, vel, pref, radius, 2.0, params, 0.1)
    assert not fallback.any()
    d = min_distance_over_horizon(pos[1] - pos[0], new[1] - new[0], tau)
    assert d >= 2 * radius - 1e-7


def test_head_on_agents_deviate_and_agents_far_apart_keep_their_preference():
    params = OrcaParams(neighbor_dist=10.0, time_horizon=2.0)
    pos = np.array([[-2.0, 0.0], [2.0, 0.0], [50.0, 50.0]])
    vel = np.array([[1.0, 0.0], [-1.0, 0.0], [0.3, 0.0]])
    new, _ = orca_velocities(pos, vel, vel, 0.5, 1.5, params, 0.1)
    assert not np.allclose(new[:2], vel[:2])
    np.testing.assert_allclose(new[2], vel[2])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_velocity_program_matches_numerical_optimum(seed):
    rng = np.random.default_rng(seed)
    k = 4
    n = rng.normal(size=(1, k, 2))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    q = rng.uniform(-0.5, 0.5, (1, k, 2))
    pref = rng.uniform(-2, 2, (1, 2))
    v, feasible = solve_velocity_lp(q, n, np.ones((1, k), bool), pref, 1.0)
    cons = [{"type": "ineq", "fun": lambda x, i=i: n[0, i] @ (x - q[0, i])} for i in range(k)]
    cons.append({"type": "ineq", "fun": lambda x: 1.0 - x @ x})
    best = None
    for x0 in rng.uniform(-0.7, 0.7, (8, 2)):
        r = minimize(lambda x: np.sum((x - pref[0]) ** 2), x0, constraints=cons, method="SLSQP", options={"ftol": 1e-14, "maxiter": 500})
        ok = r.success and all(c["fun"](r.x) >= -1e-7 for c in cons)
        if ok and (best is None or r.fun < best.fun):
            best = r
    if best is None:
        assert not feasible[0]
        return
    assert feasible[0]
    assert np.sum((v[0] - pref[0]) ** 2) <= best.fun + 1e-6
    assert all(c["fun"](v[0]) >= -1e-8 for c in cons)


def test_overlapping_agents_get_pushed_apart_within_one_step():
    q, n = orca_halfplanes(np.array([[0.3, 0.0]]), np.zeros((1, 2)), np.zeros((1, 2)), 0.5, 2.0, 0.1)
    # allowed half-plane excludes moving toward the neighbour
    assert n[0] @ (np.array([1.0, 0.0]) - q[0]) < 0


def test_crowd_stays_collision_free_without_noise():
    """Circle swap of 12 agents (ORCA may jam in symmetric crowds for other τ; this one arrives)."""
    rng = np.random.default_rng(7)
    n = 12
    ang = 2 * np.pi * np.arange(n) / n
    pos = 4.0 * np.stack([np.cos(ang), np.sin(ang)], -1)
    goals = -pos
    vel = np.zeros_like(pos)
    params = OrcaParams(neighbor_dist=5.0, max_neighbors=10, time_horizon=5.0)
    dt, radius = 0.1, 0.2
    worst = np.inf
    for _ in range(500):
        pref = preferred_velocities(pos, goals, 0.6, dt)
        pref += rng.normal(scale=1e-3, size=pref.shape)  # break the perfect symmetry
        vel, _ = orca_velocities(pos, vel, pref, radius, 0.6, params, dt)
        pos = pos + vel * dt
        d = np.linalg.norm(pos[:, None] - pos[None], axis=-1) + np.eye(n) * 1e9
        worst = min(worst, d.min())
    assert worst >= 2 * radius - 1e-6
    assert np.linalg.norm(pos - goals, axis=1).max() < 0.1


def test_least_violation_fallback_is_the_exact_minimax():
    """Sec. 5.2 fallback: the enumerated optimum lies between the LP optima over the
    circumscribed (a relaxation) and inscribed (a restriction) 360-gons of the speed disc."""
    import numpy as np
    from scipy.optimize import linprog

    from robofleet.avoidance.orca import least_violation_velocities

    rng = np.random.default_rng(21)
    m, k, sides = 60, 7, 360
    n = rng.normal(size=(m, k, 2))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    q = rng.normal(size=(m, k, 2)) * 2
    valid = rng.random((m, k)) < 0.8
    valid[:, 0] = True
    vmax = rng.uniform(0.5, 2.0, m)
    v = least_violation_velocities(q, n, valid, vmax)
    ang = 2 * np.pi * np.arange(sides) / sides
    edges = np.stack([np.cos(ang), np.sin(ang)], -1)

    def polygon_lp(nk, qk, apothem):
        A = np.vstack([np.column_stack([-nk, -np.ones(len(nk))]), np.column_stack([edges, np.zeros(sides)])])
        b = np.concatenate([-np.einsum("kd,kd->k", nk, qk), np.full(sides, apothem)])
        return linprog([0, 0, 1], A_ub=A, b_ub=b, bounds=[(None, None)] * 3, method="highs").x[2]

    for i in range(m):
        nk, qk = n[i][valid[i]], q[i][valid[i]]
        ours = np.max(np.einsum("kd,kd->k", nk, qk - v[i]))
        assert np.linalg.norm(v[i]) <= vmax[i] * (1 + 1e-9)
        relaxed = polygon_lp(nk, qk, vmax[i])  # circumscribed: apothem = radius
        restricted = polygon_lp(nk, qk, vmax[i] * np.cos(np.pi / sides))  # inscribed
        assert relaxed - 1e-9 <= ours <= restricted + 1e-9
