"""Optimal reciprocal collision avoidance (ORCA) — J. van den Berg, S. J. Guy, M. Lin,
D. Manocha, "Reciprocal n-body collision avoidance", Robotics Research (STAR 70), 2011.

The baseline of Zhu et al. 2022 for holonomic robots. One step, per agent (compiled,
agents in parallel, :func:`orca_velocities`):

1. *Neighbours* — up to ``max_neighbors`` nearest agents closer than ``neighbor_dist``,
   nearest first (uniform grid, :func:`~.neighbours.nearest_neighbours`).
2. *ORCA half-planes* (Sec. 4 of the paper, Eq. (5)): for agents A, B with relative
   position ``p = p_B − p_A``, relative velocity ``v = v_A − v_B``, combined radius
   ``r`` and horizon ``τ``, the velocity obstacle ``VO^τ`` is the cone from the origin
   tangent to the disc ``D(p, r)``, truncated by the disc ``D(p/τ, r/τ)``. ``u`` is the
   vector from ``v`` to the closest point of ``∂VO^τ`` and ``n`` the outward normal
   there; ``ORCA_A = {v' : (v' − (v_A + u/2))·n ≥ 0}``. Agents already overlapping use
   the cut-off disc ``D(p/Δt, r/Δt)`` (resolve within one step).
   Static polygon obstacles and walls (:mod:`.orca_obstacles`, Sec. 5 and RVO2) add one
   half-plane per visible edge within ``τ_o v_max + r``, which the agent keeps alone (no
   factor ½); they come first.
3. *Velocity selection* (Eq. (6), Sec. 5.1): the velocity nearest to ``v_pref`` in
   ``D(0, v_max) ∩ ⋂ ORCA``, by the incremental 2-D linear program of the paper: take
   the optimum so far; when the next half-plane excludes it, the new optimum lies on
   that half-plane's line, a 1-D program over the interval the disc and the earlier
   half-planes leave on it (O(K) expected per agent, K ≤ ``max_neighbors``).
4. *Infeasible programs* (Sec. 5.2, dense crowds): the velocity minimising the largest
   violation ``max_k n_k·(q_k − v)`` over the disc, a 3-D linear program solved by the
   same incremental scheme — when half-plane k is violated by more than the current
   maximum, the new optimum makes k the largest violation, i.e. it maximises ``n_k·v``
   over the disc and the lines ``{v : n_j·(q_j − v) ≤ n_k·(q_k − v)}``, j < k (a 2-D
   program with a linear objective). The obstacles' half-planes stay hard constraints of
   every such program: only the agents' are traded.

With exact positions and ``τ_o ≥ Δt``, a robot whose obstacle half-planes are feasible
moves, over the step, only along velocities outside every visible edge's velocity
obstacle, so it never comes closer than its radius to an obstacle or a wall
(``tests/avoidance/test_orca_obstacles.py`` checks it on random scenes).

The vectorized forms :func:`orca_halfplanes`, :func:`solve_velocity_lp` and
:func:`least_violation_velocities` (exact enumeration of the optimality conditions) are
kept as independent references the tests compare the kernel against.
"""

from __future__ import annotations

import numba
import numpy as np

from ..core.errors import ConfigError
from .controller_params import OrcaParams
from .kernels import use_parallel
from .neighbours import nearest_neighbours
from .orca_obstacles import ObstacleEdges, nearby_edges, no_obstacles, obstacle_lines

_EPS = 1e-12


def neighbours(positions: np.ndarray, params: OrcaParams) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(N, K)`` of each agent's nearest neighbours (closer than
    ``neighbor_dist``, nearest first) and a validity mask ``(N, K)``."""
    n = len(positions)
    k = min(params.max_neighbors, n - 1)
    if k <= 0:
        return np.zeros((n, 0), dtype=np.intp), np.zeros((n, 0), dtype=bool)
    idx, count = nearest_neighbours(positions, k, params.neighbor_dist)
    ok = np.arange(k)[None] < count[:, None]
    return np.where(ok, idx, 0).astype(np.intp), ok


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
    N = q.shape[0]
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


def orca_velocities(positions: np.ndarray, velocities: np.ndarray, v_pref: np.ndarray, radius: float | np.ndarray, v_max: float | np.ndarray, params: OrcaParams, dt: float,
                    obstacles: ObstacleEdges | None = None) -> tuple[np.ndarray, np.ndarray]:
    """New velocities ``(N, 2)`` of every agent (one ORCA step; see the module docstring).

    Parameters
    ----------
    positions, velocities : (N, 2) as sensed by the agents
    v_pref : (N, 2) preferred velocities (toward the goal)
    radius : agent radius (scalar or ``(N,)``); v_max : speed limit (scalar or ``(N,)``)
    params : neighbour distance, max neighbours, time horizons
    dt : simulation step
    obstacles : static polygons and walls (:class:`~.orca_obstacles.ObstacleEdges`); their
        lines come first and the fallback never relaxes them

    Returns
    -------
    velocities : (N, 2)
    infeasible : (N,) bool, agents that used the least-violation fallback

    Each agent reads only the others' positions and velocities, so the agents run in
    parallel (:mod:`.kernels`) with the same result on any number of threads.
    """
    pos = np.ascontiguousarray(positions, dtype=np.float64)
    vel = np.ascontiguousarray(velocities, dtype=np.float64)
    pref = np.ascontiguousarray(v_pref, dtype=np.float64)
    N = len(pos)
    for name, value in (("positions", pos), ("velocities", vel), ("v_pref", pref)):
        if value.shape != (N, 2):  # the compiled kernel reads them unchecked
            raise ConfigError(f"{name}: expected an array ({N}, 2), received shape {value.shape}")
    try:
        rad = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, dtype=np.float64), (N,)))
        vmax = np.ascontiguousarray(np.broadcast_to(np.asarray(v_max, dtype=np.float64), (N,)))
    except ValueError:
        raise ConfigError(f"radius, v_max: expected numbers or arrays ({N},), received shapes {np.shape(radius)}, {np.shape(v_max)}") from None
    k = max(min(params.max_neighbors, N - 1), 0)
    idx, count = nearest_neighbours(pos, k, params.neighbor_dist)
    new, infeasible = np.empty((N, 2)), np.empty(N, np.bool_)
    walls = no_obstacles() if obstacles is None or obstacles.count == 0 or N == 0 else \
        obstacles.arrays(float(params.time_horizon_obst * vmax.max() + rad.max()))
    args = (pos, vel, pref, rad, vmax, idx, count, float(params.time_horizon), float(dt), new, infeasible,
            float(params.time_horizon_obst), *walls)
    if use_parallel(N):
        _orca_parallel(*args)
    else:
        _orca_range(0, N, *args)
    return new, infeasible


_CHUNK = 256  # agents per parallel task (one set of scratch lines each)


@numba.njit(cache=True, parallel=True)
def _orca_parallel(pos, vel, pref, rad, vmax, idx, count, tau, dt, new, infeasible,
                   tau_obst, point, nxt, prv, unit, convex, origin, h, nx, ny, start, edges, first_cell, most):
    n = len(pos)
    for c in numba.prange((n + _CHUNK - 1) // _CHUNK):
        _orca_range(c * _CHUNK, min(n, (c + 1) * _CHUNK), pos, vel, pref, rad, vmax, idx, count, tau, dt, new, infeasible,
                    tau_obst, point, nxt, prv, unit, convex, origin, h, nx, ny, start, edges, first_cell, most)


@numba.njit(cache=True)
def _orca_range(lo, hi, pos, vel, pref, rad, vmax, idx, count, tau, dt, new, infeasible,
                tau_obst, point, nxt, prv, unit, convex, origin, h, nx, ny, start, edges, first_cell, most):
    """Agents ``lo … hi − 1``: obstacle lines (:mod:`.orca_obstacles`), then the agents'
    half-planes (step 2), 2-D program (3), fallback keeping the obstacle lines (4)."""
    k, n_edges = idx.shape[1], len(point)
    lines = np.empty((most + max(k, 1), 4))  # q_x, q_y, n_x, n_y: obstacle lines first
    scratch = np.empty((most + max(k, 1), 4))
    dist, found = np.empty(max(most, 1)), np.empty(max(most, 1), np.int64)
    for i in range(lo, hi):
        fixed = 0
        if n_edges:
            near = nearby_edges(pos[i, 0], pos[i, 1], tau_obst * vmax[i] + rad[i], point, nxt, origin, h, nx, ny, start, edges, first_cell,
                                dist, found)
            fixed = obstacle_lines(pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1], rad[i], tau_obst, found, near, point, nxt, prv, unit, convex, lines)
        m = count[i]
        for t in range(m):
            j = idx[i, t]
            halfplane(pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], vel[i, 0] - vel[j, 0], vel[i, 1] - vel[j, 1],
                      vel[i, 0], vel[i, 1], rad[i] + rad[j], tau, dt, lines, fixed + t)
        total = fixed + m
        failed, v0, v1 = program_2d(lines, total, vmax[i], pref[i, 0], pref[i, 1], False)
        if failed < total:
            v0, v1 = program_3d(lines, total, failed, vmax[i], v0, v1, scratch, fixed)
        new[i, 0], new[i, 1], infeasible[i] = v0, v1, failed < total


@numba.njit(cache=True)
def halfplane(p0, p1, w0_rel, w1_rel, own0, own1, r, tau, dt, lines, t):
    """ORCA half-plane of one pair into ``lines[t] = (q, n)`` (Sec. 4, Eq. (5); the same
    cases as :func:`orca_halfplanes`): ``p`` relative position, ``v`` relative velocity."""
    dist2 = p0 * p0 + p1 * p1
    overlap = dist2 <= r * r
    inv_t = 1.0 / dt if overlap else 1.0 / tau
    w0, w1 = w0_rel - p0 * inv_t, w1_rel - p1 * inv_t
    w_len = np.sqrt(w0 * w0 + w1 * w1)
    unit0, unit1 = w0 / max(w_len, _EPS), w1 / max(w_len, _EPS)
    w_dot_p = w0 * p0 + w1 * p1
    if overlap or (w_dot_p < 0 and w_dot_p * w_dot_p > r * r * w_len * w_len):  # cut-off disc
        u_scale = r * inv_t - w_len
        u0, u1, n0, n1 = u_scale * unit0, u_scale * unit1, unit0, unit1
    else:  # a leg of the cone: tangent from the origin to D(p, r)
        leg = np.sqrt(max(dist2 - r * r, 0.0))
        left = (p0 * w1 - p1 * w0) > 0
        rot = r if left else -r
        scale = max(dist2, _EPS)
        d0, d1 = (p0 * leg - p1 * rot) / scale, (p0 * rot + p1 * leg) / scale
        n0, n1 = (-d1, d0) if left else (d1, -d0)
        along = w0_rel * d0 + w1_rel * d1
        u0, u1 = along * d0 - w0_rel, along * d1 - w1_rel
    lines[t, 0], lines[t, 1], lines[t, 2], lines[t, 3] = own0 + 0.5 * u0, own1 + 0.5 * u1, n0, n1


@numba.njit(cache=True)
def program_1d(lines, k, radius, c0, c1, direction):
    """Sec. 5.1, on line k: the best point ``q_k + s d_k`` (``d_k = n_k`` turned by −90°)
    in the disc and the half-planes ``0 … k − 1``: nearest to ``c`` or, with
    ``direction``, furthest along ``c``. Returns ``(ok, v_x, v_y)``."""
    q0, q1, n0, n1 = lines[k, 0], lines[k, 1], lines[k, 2], lines[k, 3]
    d0, d1 = n1, -n0
    qd = q0 * d0 + q1 * d1
    disc = qd * qd + radius * radius - (q0 * q0 + q1 * q1)
    if disc < 0.0:
        return False, 0.0, 0.0
    root = np.sqrt(disc)
    lo, hi = -qd - root, -qd + root
    for j in range(k):
        rate = lines[j, 2] * d0 + lines[j, 3] * d1  # n_j·d_k
        need = lines[j, 2] * (lines[j, 0] - q0) + lines[j, 3] * (lines[j, 1] - q1)  # n_j·(q_j − q_k)
        if abs(rate) <= _EPS:
            if need > 0.0:  # line k lies outside half-plane j
                return False, 0.0, 0.0
            continue
        if rate > 0.0:
            lo = max(lo, need / rate)
        else:
            hi = min(hi, need / rate)
        if lo > hi:
            return False, 0.0, 0.0
    if direction:
        s = hi if c0 * d0 + c1 * d1 > 0.0 else lo
    else:
        s = min(max((c0 - q0) * d0 + (c1 - q1) * d1, lo), hi)
    return True, q0 + s * d0, q1 + s * d1


@numba.njit(cache=True)
def program_2d(lines, m, radius, c0, c1, direction):
    """Sec. 5.1: nearest point to ``c`` (or, with ``direction``, furthest along the unit
    ``c``) in the disc ``D(0, radius)`` and the half-planes ``0 … m − 1``, adding the
    half-planes one at a time. Returns ``(failed, v_x, v_y)``: ``failed = m`` when
    feasible, else the first half-plane that emptied the program, with the optimum of
    the ones before it."""
    if direction:
        v0, v1 = c0 * radius, c1 * radius
    else:
        speed2 = c0 * c0 + c1 * c1
        scale = radius / np.sqrt(speed2) if speed2 > radius * radius else 1.0
        v0, v1 = c0 * scale, c1 * scale
    for k in range(m):
        if lines[k, 2] * (v0 - lines[k, 0]) + lines[k, 3] * (v1 - lines[k, 1]) < 0.0:
            ok, x0, x1 = program_1d(lines, k, radius, c0, c1, direction)
            if not ok:
                return k, v0, v1
            v0, v1 = x0, x1
    return m, v0, v1


@numba.njit(cache=True)
def program_3d(lines, m, begin, radius, v0, v1, scratch, fixed):
    """Sec. 5.2: minimise the largest violation ``max_k n_k·(q_k − v)`` over the disc,
    starting from the optimum of half-planes ``0 … begin − 1`` (violation ≤ 0). The
    first ``fixed`` lines (the obstacles') stay hard constraints and are never traded."""
    worst = 0.0
    for k in range(begin, m):
        qk0, qk1, nk0, nk1 = lines[k, 0], lines[k, 1], lines[k, 2], lines[k, 3]
        if nk0 * (qk0 - v0) + nk1 * (qk1 - v1) <= worst:
            continue
        for j in range(fixed):
            scratch[j, 0], scratch[j, 1], scratch[j, 2], scratch[j, 3] = lines[j, 0], lines[j, 1], lines[j, 2], lines[j, 3]
        rows = fixed
        for j in range(fixed, k):  # {v : n_j·(q_j − v) ≤ n_k·(q_k − v)}
            w0, w1 = lines[j, 2] - nk0, lines[j, 3] - nk1
            w_len = np.sqrt(w0 * w0 + w1 * w1)
            if w_len <= _EPS:  # same direction: line k dominates j everywhere
                continue
            offset = (lines[j, 2] * lines[j, 0] + lines[j, 3] * lines[j, 1] - nk0 * qk0 - nk1 * qk1) / w_len
            u0, u1 = w0 / w_len, w1 / w_len
            scratch[rows, 0], scratch[rows, 1], scratch[rows, 2], scratch[rows, 3] = u0 * offset, u1 * offset, u0, u1
            rows += 1
        failed, x0, x1 = program_2d(scratch, rows, radius, nk0, nk1, True)
        if failed == rows:  # always feasible in exact arithmetic; keep the last point otherwise
            v0, v1 = x0, x1
        worst = nk0 * (qk0 - v0) + nk1 * (qk1 - v1)
    return v0, v1


def preferred_velocities(positions: np.ndarray, goals: np.ndarray, v_max: float | np.ndarray, dt: float) -> np.ndarray:
    """``v_pref``: toward the goal at ``min(v_max, distance/Δt)``."""
    gap = goals - positions
    dist = np.linalg.norm(gap, axis=-1, keepdims=True)
    vmax = np.asarray(v_max, dtype=float)
    vmax = vmax[..., None] if vmax.ndim else vmax
    return gap / np.maximum(dist, _EPS) * np.minimum(vmax, dist / dt)
