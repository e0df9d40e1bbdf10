"""Optimal reciprocal collision avoidance (ORCA) — J. van den Berg, S. J. Guy, M. Lin,
D. Manocha, "Reciprocal n-body collision avoidance", Robotics Research (STAR 70), 2011.

The baseline of paper 003 for holonomic robots, vectorized over agents:

1. *Neighbours* — up to ``max_neighbors`` nearest agents within ``neighbor_dist``
   (k-d tree).
2. *ORCA half-planes* (Sec. 4 of the paper, Eq. (5)): for agents A, B with relative
   position ``p = p_B − p_A``, relative velocity ``v = v_A − v_B``, combined radius
   ``r`` and horizon ``τ``, the velocity obstacle ``VO^τ`` is the cone from the origin
   tangent to the disc ``D(p, r)``, truncated by the disc ``D(p/τ, r/τ)``. ``u`` is the
   vector from ``v`` to the closest point of ``∂VO^τ`` and ``n`` the outward normal
   there; ``ORCA_A = {v' : (v' − (v_A + u/2))·n ≥ 0}``. Agents already overlapping use
   the cut-off disc ``D(p/Δt, r/Δt)`` (resolve within one step).
3. *Velocity selection* (Eq. (6)): the velocity nearest to ``v_pref`` in
   ``D(0, v_max) ∩ ⋂ ORCA``. This 2-D program is solved exactly for all agents at once
   by candidate enumeration: the optimum is either ``v_pref`` clipped to the speed disc
   or the projection of ``v_pref`` onto one constraint line restricted to the feasible
   interval cut by the disc and the other half-planes. When the program is infeasible
   (dense crowds), Sec. 5.2's fallback is used: the velocity minimising the largest
   violation, solved per infeasible agent as a small LP over a polygonal speed disc.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field
from scipy.optimize import linprog
from scipy.spatial import cKDTree

from ..scenarios.base import SpecModel

_EPS = 1e-12


class OrcaParams(SpecModel):
    """ORCA parameters (names as in the paper's reference library)."""

    neighbor_dist: float = Field(3.0, gt=0, description="sensing range for neighbours [m]")
    max_neighbors: int = Field(10, ge=1, description="neighbours considered per agent")
    time_horizon: float = Field(2.0, gt=0, description="τ: collision-free horizon w.r.t. agents [s]")


def neighbours(positions: np.ndarray, params: OrcaParams) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(N, K)`` of each agent's nearest neighbours and a validity mask ``(N, K)``."""
    n = len(positions)
    k = min(params.max_neighbors, n - 1)
    if k <= 0:
        return np.zeros((n, 0), dtype=np.intp), np.zeros((n, 0), dtype=bool)
    dist, idx = cKDTree(positions).query(positions, k=k + 1, distance_upper_bound=params.neighbor_dist)
    dist, idx = dist[:, 1:], idx[:, 1:]
    ok = np.isfinite(dist) & (idx < n)
    return np.where(ok, idx, 0), ok


def orca_halfplanes(rel_pos, rel_vel, own_vel, radius, tau: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """ORCA half-planes ``{v : n·(v − q) ≥ 0}`` for arrays of agent pairs ``(..., 2)``.

    Parameters
    ----------
    rel_pos : ``p_B − p_A``;  rel_vel : ``v_A − v_B``;  own_vel : ``v_A``
    radius : combined radius ``r_A + r_B`` (scalar or ``(...)``)
    tau : time horizon;  dt : step (used when the agents already overlap)

    Returns
    -------
    q : (..., 2) a point on the boundary line, ``v_A + u/2``
    n : (..., 2) unit inward normal of the allowed half-plane
    """
    p = np.asarray(rel_pos, dtype=float)
    v = np.asarray(rel_vel, dtype=float)
    r = np.broadcast_to(np.asarray(radius, dtype=float), p.shape[:-1])
    dist2 = np.einsum("...d,...d->...", p, p)
    overlap = dist2 <= r * r
    inv_t = np.where(overlap, 1.0 / dt, 1.0 / tau)
    w = v - p * inv_t[..., None]
    w_len = np.linalg.norm(w, axis=-1)
    w_unit = w / np.maximum(w_len, _EPS)[..., None]
    w_dot_p = np.einsum("...d,...d->...", w, p)
    # the cut-off disc is closest when w points away from the cone apex side
    on_disc = overlap | ((w_dot_p < 0) & (w_dot_p**2 > r * r * w_len**2))
    u_disc = (r * inv_t - w_len)[..., None] * w_unit
    # legs: tangent directions from the origin to D(p, r)
    leg = np.sqrt(np.maximum(dist2 - r * r, 0.0))
    left = (p[..., 0] * w[..., 1] - p[..., 1] * w[..., 0]) > 0
    rot_sin = np.where(left, r, -r)
    d = np.stack([p[..., 0] * leg - p[..., 1] * rot_sin, p[..., 0] * rot_sin + p[..., 1] * leg], -1) / np.maximum(dist2, _EPS)[..., None]
    normal_leg = np.where(left[..., None], np.stack([-d[..., 1], d[..., 0]], -1), np.stack([d[..., 1], -d[..., 0]], -1))
    u_leg = np.einsum("...d,...d->...", v, d)[..., None] * d - v
    u = np.where(on_disc[..., None], u_disc, u_leg)
    n_out = np.where(on_disc[..., None], w_unit, normal_leg)
    return own_vel + 0.5 * u, n_out


def solve_velocity_lp(q: np.ndarray, n: np.ndarray, valid: np.ndarray, v_pref: np.ndarray, v_max) -> tuple[np.ndarray, np.ndarray]:
    """Nearest velocity to ``v_pref`` in ``D(0, v_max) ∩ {n_k·(v − q_k) ≥ 0}``, all agents at once.

    ``q, n (N, K, 2)``, ``valid (N, K)``, ``v_pref (N, 2)``, ``v_max`` scalar or ``(N,)``.
    Returns the velocities ``(N, 2)`` and a feasibility mask ``(N,)``; infeasible agents
    get ``v_pref`` clipped (the caller applies the fallback).
    """
    N, K, _ = q.shape
    vmax = np.broadcast_to(np.asarray(v_max, dtype=float), (N,))
    # inactive (padded) constraints: n·v ≥ −1e9, never binding
    n = np.where(valid[..., None], n, np.array([1.0, 0.0]))
    q = np.where(valid[..., None], q, np.array([-1e9, 0.0]))
    speed = np.linalg.norm(v_pref, axis=-1)
    c0 = v_pref * np.minimum(1.0, vmax / np.maximum(speed, _EPS))[:, None]
    c0_ok = np.all(np.einsum("nkd,nkd->nk", n, c0[:, None, :] - q) >= -1e-9, axis=1)
    # candidates on each line k: q_k + s·d_k, d_k = n_k rotated by −90°
    d = np.stack([n[..., 1], -n[..., 0]], -1)
    qd = np.einsum("nkd,nkd->nk", q, d)
    disc = qd**2 - (np.einsum("nkd,nkd->nk", q, q) - vmax[:, None] ** 2)
    root = np.sqrt(np.maximum(disc, 0.0))
    lo, hi = -qd - root, -qd + root
    rate = np.einsum("nld,nkd->nkl", n, d)  # n_l·d_k
    need = np.einsum("nld,nld->nl", n, q)[:, None, :] - np.einsum("nld,nkd->nkl", n, q)  # n_l·(q_l − q_k)
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = need / rate
    lo = np.maximum(lo, np.where(rate > _EPS, bound, -np.inf).max(axis=2))
    hi = np.minimum(hi, np.where(rate < -_EPS, bound, np.inf).min(axis=2))
    parallel_bad = np.any((np.abs(rate) <= _EPS) & (need > 1e-9), axis=2)
    line_ok = valid & (disc >= 0) & (lo <= hi + 1e-12) & ~parallel_bad
    s = np.clip(np.einsum("nkd,nkd->nk", v_pref[:, None, :] - q, d), lo, hi)
    cand = q + s[..., None] * d
    dist = np.where(line_ok, np.linalg.norm(cand - v_pref[:, None, :], axis=-1), np.inf)
    best = np.argmin(dist, axis=1)
    line_best = cand[np.arange(N), best]
    feasible = c0_ok | np.isfinite(dist[np.arange(N), best])
    return np.where(c0_ok[:, None], c0, np.where(feasible[:, None], line_best, c0)), feasible


def least_violation_velocity(q: np.ndarray, n: np.ndarray, v_max: float, sides: int = 32) -> np.ndarray:
    """Sec. 5.2 fallback for one agent: ``argmin_v max_k −n_k·(v − q_k)`` over ``‖v‖ ≤ v_max``.

    Solved as an LP in ``(v, t)`` with the speed disc replaced by its inscribed regular
    ``sides``-gon.
    """
    angles = 2 * np.pi * np.arange(sides) / sides
    edge_n = np.stack([np.cos(angles), np.sin(angles)], -1)
    apothem = v_max * np.cos(np.pi / sides)
    A_ub = np.vstack([np.column_stack([-n, -np.ones(len(n))]), np.column_stack([edge_n, np.zeros(sides)])])
    b_ub = np.concatenate([-np.einsum("kd,kd->k", n, q), np.full(sides, apothem)])
    res = linprog([0.0, 0.0, 1.0], A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 3, method="highs")
    return res.x[:2] if res.success else np.zeros(2)


def orca_velocities(positions, velocities, v_pref, radius, v_max, params: OrcaParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """New velocities ``(N, 2)`` of every agent (one ORCA step, all agents at once).

    Parameters
    ----------
    positions, velocities : (N, 2) as sensed by the agents
    v_pref : (N, 2) preferred velocities (toward the goal)
    radius : agent radius (scalar or ``(N,)``); v_max : speed limit (scalar or ``(N,)``)
    params : neighbour distance, max neighbours, time horizon
    dt : simulation step

    Returns
    -------
    velocities : (N, 2)
    infeasible : (N,) bool, agents that used the least-violation fallback
    """
    pos = np.asarray(positions, dtype=float)
    vel = np.asarray(velocities, dtype=float)
    N = len(pos)
    rad = np.broadcast_to(np.asarray(radius, dtype=float), (N,))
    vmax = np.broadcast_to(np.asarray(v_max, dtype=float), (N,))
    idx, valid = neighbours(pos, params)
    q, n = orca_halfplanes(pos[idx] - pos[:, None, :], vel[:, None, :] - vel[idx], vel[:, None, :], rad[:, None] + rad[idx], params.time_horizon, dt)
    new, feasible = solve_velocity_lp(q, n, valid, np.asarray(v_pref, dtype=float), vmax)
    for i in np.flatnonzero(~feasible):
        new[i] = least_violation_velocity(q[i][valid[i]], n[i][valid[i]], float(vmax[i]))
    return new, ~feasible


def preferred_velocities(positions, goals, v_max, dt: float) -> np.ndarray:
    """``v_pref``: toward the goal at ``min(v_max, distance/Δt)``."""
    gap = goals - positions
    dist = np.linalg.norm(gap, axis=-1, keepdims=True)
    vmax = np.asarray(v_max, dtype=float)
    vmax = vmax[..., None] if vmax.ndim else vmax
    return gap / np.maximum(dist, _EPS) * np.minimum(vmax, dist / dt)
