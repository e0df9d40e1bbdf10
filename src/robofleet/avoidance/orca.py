"""Optimal reciprocal collision avoidance (ORCA) — J. van den Berg, S. J. Guy, M. Lin,
D. Manocha, "Reciprocal n-body collision avoidance", Robotics Research (STAR 70), 2011.

The baseline of Zhu et al. 2022 for holonomic robots, vectorized over agents:

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
   violation, found exactly for all infeasible agents at once by enumerating the
   candidates the optimality conditions allow (:func:`least_violation_velocities`).
"""

from __future__ import annotations

import numba
import numpy as np
from pydantic import Field
from scipy.spatial import cKDTree

from ..core.config import SpecModel

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


def orca_halfplanes(rel_pos: np.ndarray, rel_vel: np.ndarray, own_vel: np.ndarray, radius: float | np.ndarray, tau: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
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


def solve_velocity_lp(q: np.ndarray, n: np.ndarray, valid: np.ndarray, v_pref: np.ndarray, v_max: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def least_violation_velocities(q: np.ndarray, n: np.ndarray, valid: np.ndarray, v_max: np.ndarray) -> np.ndarray:
    """Sec. 5.2 fallback, exact, for a batch of agents: ``argmin_v max_k g_k(v)`` over
    ``‖v‖ ≤ v_max``, with the violations ``g_k(v) = n_k·(q_k − v)``.

    ``f = max_k g_k`` is convex and piecewise linear, so its minimiser over the disc is,
    by the optimality conditions, one of: a point where three violations are equal
    (interior, ``0 ∈ conv{∇g}``); ``v_max n_k`` (on the circle with one active
    constraint); a point of the circle where two violations are equal. All candidates
    are enumerated (O(K³) per agent, K ≤ ``max_neighbors``) and the best kept.
    ``q, n (M, K, 2)``, ``valid (M, K)``, ``v_max (M,)``; returns ``(M, 2)``.
    """
    out = np.zeros((len(q), 2))
    _least_violation(np.ascontiguousarray(q, dtype=np.float64), np.ascontiguousarray(n, dtype=np.float64),
                     np.ascontiguousarray(valid), np.ascontiguousarray(v_max, dtype=np.float64), out)
    return out


@numba.njit(cache=True)
def _worst_violation(v0, v1, q, n, valid, i):
    worst = -np.inf
    for k in range(q.shape[1]):
        if valid[i, k]:
            g = n[i, k, 0] * (q[i, k, 0] - v0) + n[i, k, 1] * (q[i, k, 1] - v1)
            worst = max(worst, g)
    return worst


@numba.njit(cache=True)
def _least_violation(q, n, valid, v_max, out):
    tol = 1e-12
    for i in range(q.shape[0]):
        r = v_max[i]
        rows = [k for k in range(q.shape[1]) if valid[i, k]]
        c = [n[i, k, 0] * q[i, k, 0] + n[i, k, 1] * q[i, k, 1] for k in rows]
        best, b0, b1 = np.inf, 0.0, 0.0
        m = len(rows)
        for a in range(m):  # one active constraint on the circle: v = r n_k
            k = rows[a]
            v0, v1 = r * n[i, k, 0], r * n[i, k, 1]
            f = _worst_violation(v0, v1, q, n, valid, i)
            if f < best:
                best, b0, b1 = f, v0, v1
        for a in range(m):
            ka = rows[a]
            for b in range(a + 1, m):
                kb = rows[b]
                # circle points with g_a = g_b: (n_b − n_a)·v = c_b − c_a
                w0, w1 = n[i, kb, 0] - n[i, ka, 0], n[i, kb, 1] - n[i, ka, 1]
                h = c[b] - c[a]
                ww = w0 * w0 + w1 * w1
                if ww > tol:
                    foot0, foot1 = h * w0 / ww, h * w1 / ww
                    rest = r * r - (foot0 * foot0 + foot1 * foot1)
                    if rest >= 0.0:
                        t = np.sqrt(rest / ww)
                        for sgn in (-1.0, 1.0):
                            v0, v1 = foot0 - sgn * t * w1, foot1 + sgn * t * w0
                            f = _worst_violation(v0, v1, q, n, valid, i)
                            if f < best:
                                best, b0, b1 = f, v0, v1
                for cc in range(b + 1, m):  # interior points with g_a = g_b = g_c
                    kc = rows[cc]
                    u0, u1 = n[i, kc, 0] - n[i, ka, 0], n[i, kc, 1] - n[i, ka, 1]
                    det = w0 * u1 - w1 * u0
                    if abs(det) <= tol:
                        continue
                    hc = c[cc] - c[a]
                    v0 = (h * u1 - hc * w1) / det
                    v1 = (w0 * hc - u0 * h) / det
                    if v0 * v0 + v1 * v1 <= r * r * (1.0 + 1e-12):
                        f = _worst_violation(v0, v1, q, n, valid, i)
                        if f < best:
                            best, b0, b1 = f, v0, v1
        out[i, 0], out[i, 1] = b0, b1


def orca_velocities(positions: np.ndarray, velocities: np.ndarray, v_pref: np.ndarray, radius: float | np.ndarray, v_max: float | np.ndarray, params: OrcaParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
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
    stuck = np.flatnonzero(~feasible)
    if len(stuck):
        new[stuck] = least_violation_velocities(q[stuck], n[stuck], valid[stuck], vmax[stuck])
    return new, ~feasible


def preferred_velocities(positions: np.ndarray, goals: np.ndarray, v_max: float | np.ndarray, dt: float) -> np.ndarray:
    """``v_pref``: toward the goal at ``min(v_max, distance/Δt)``."""
    gap = goals - positions
    dist = np.linalg.norm(gap, axis=-1, keepdims=True)
    vmax = np.asarray(v_max, dtype=float)
    vmax = vmax[..., None] if vmax.ndim else vmax
    return gap / np.maximum(dist, _EPS) * np.minimum(vmax, dist / dt)
