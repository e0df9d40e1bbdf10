"""Solve time of the B-UAVC MPC per robot-step (Zhu et al. 2022 receding-horizon control).

Runs a circle swap with real B-UAVC cells recomputed every step from noisy estimates
and times every per-robot solve:

* single integrator, N = 10, Δt = 0.1 s, 8 robots in 2D (QP, qpOASES) — target ≤ 10 ms median;
* quadrotor (appendix D), N = 20, Δt = 0.05 s, 6 robots in 3D, speed limit 1 m/s, with
  ``rti`` (the default: braking-safe condensed Gauss–Newton SQP around the shifted plan,
  DAQP QPs, :mod:`robofleet.avoidance.rti`) and ``ipopt`` (the full NLP of the same
  problem, the SQP as its recovery), and, for reference, IPOPT on the problem as it was
  before issue 10 (no terminal rest set, no speed limit, braking when it fails) —
  targets (issue 10) median ≤ 5 ms, p95 ≤ 15 ms, fallback ≤ 1 % of robot-steps.

Usage: ``python benchmarks/mpc.py [--steps S] [--seed K] [--sigma S]``. Prints median and
95th percentile (milliseconds), wall-clock and CPU time of the solving thread, and the
share of solves without an in-cell plan (``fallback``), overall and among the solves whose
position estimate lay inside its own cell (``fb|in cell``; outside it the first predicted
position, fixed by the current velocity, cannot be in the cell), and the share of solves
that had to brake (no plan at all; the others apply the least-violating plan).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _machine import machine

from robofleet.avoidance.buffer import confidence_quantile
from robofleet.avoidance.cell import CellGeometry, build_cells
from robofleet.avoidance.cell3d import workspace_box_planes
from robofleet.avoidance.mpc import BuavcMPC, MPCConfig, SingleIntegratorParams
from robofleet.avoidance.obstacles import ObstacleSet
from robofleet.dynamics import quadrotor as quad


def circle(n, radius, dim, height=1.5):
    ang = 2 * np.pi * np.arange(n) / n
    pts = np.zeros((n, dim))
    pts[:, 0], pts[:, 1] = radius * np.cos(ang), radius * np.sin(ang)
    if dim == 3:
        pts[:, 2] = height + 0.3 * np.where(np.arange(n) % 2, 1, -1)
    goals = pts.copy()
    goals[:, :2] *= -1
    return pts, goals


def run(model, params, dim, dt, horizon, n, steps, sigma, seed=0, speed_limit=None, **options):
    rng = np.random.default_rng(seed)
    lo, hi = ([-5, -5], [5, 5]) if dim == 2 else ([-5, -5, 0], [5, 5, 3])
    wall_a, wall_b = workspace_box_planes(lo, hi)
    geometry = CellGeometry(ObstacleSet.build([], [], 0.05), wall_a, wall_b)
    start, goals = circle(n, 4.0 if dim == 2 else 3.0, dim)
    state = np.zeros((n, 2 * dim if model == "double_integrator" else (9 if model == "quadrotor" else dim)))
    state[:, :dim] = start
    mpc = BuavcMPC(model, params, dim=dim, dt=dt, config=MPCConfig(horizon=horizon, **options), n_robots=n, speed_limit=speed_limit,
                   position_sigma=sigma)
    cov = np.repeat((sigma**2 * np.eye(dim))[None], n, 0)
    q = confidence_quantile(0.1)
    times, cpu, fallbacks, in_cell, fallbacks_in_cell, brakes = [], [], 0, 0, 0, 0
    for _ in range(steps):
        est = state[:, :dim] + rng.normal(scale=sigma, size=(n, dim))
        cells = build_cells(est, cov, np.full(n, 0.2), q, geometry, 2.0)
        s_est = state.copy()
        s_est[:, :dim] = est
        for i in range(n):
            A, b = mpc.cell_parameters(cells.A[i], cells.b[i], cells.valid[i], est[i])
            t0, c0 = time.perf_counter(), time.thread_time()
            result = mpc.plan(i, s_est[i], goals[i], A, b)
            times.append(time.perf_counter() - t0)
            cpu.append(time.thread_time() - c0)
            fallbacks += not result.in_cell
            brakes += result.control is None
            inside = bool(np.all(A @ est[i] <= b))
            in_cell += inside
            fallbacks_in_cell += inside and not result.in_cell
            u = mpc.model.fallback(s_est[i:i + 1])[0] if result.control is None else result.control
            state[i] = state[i] + u * dt if model == "single_integrator" else quad.step(state[i:i + 1], u[None], dt, params)[0]
    t, c = np.array(times) * 1e3, np.array(cpu) * 1e3
    return {"median": np.median(t), "p95": np.percentile(t, 95), "cpu_median": np.median(c), "cpu_p95": np.percentile(c, 95),
            "solves": len(t), "fallbacks": fallbacks, "brakes": brakes,
            "in_cell": in_cell, "fallbacks_in_cell": fallbacks_in_cell}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sigma", type=float, default=0.05, help="σ of the quadrotors' estimates (2-D rows: 0.1)")
    args = parser.parse_args()
    quadrotor = ("quadrotor", quad.QuadrotorParams(), 3, 0.05, 20, 6, 5.0)
    rows = [
        ("single integrator N=10 dt=0.1", "single_integrator", SingleIntegratorParams(v_max=0.4), 2, 0.1, 10, 8, 10.0, {}),
        ("quadrotor N=20 rti (default)", *quadrotor, {"solver": "rti", "speed_limit": 1.0}),
        ("quadrotor N=20 ipopt", *quadrotor, {"solver": "ipopt", "speed_limit": 1.0}),
        ("quadrotor ipopt before issue 10", *quadrotor, {"solver": "ipopt", "terminal_rest": False, "legacy": True}),
    ]
    print(machine())
    print("wall = elapsed time per solve; cpu = CPU time of the solving thread (insensitive to other load)")
    print(f"{'problem':32s} {'solves':>6s} {'fallback':>8s} {'fb|in cell':>9s} {'brake':>6s} {'wall med':>9s} {'wall p95':>9s} "
          f"{'cpu med':>8s} {'cpu p95':>8s} {'target':>7s}  median/target")
    for label, model, params, dim, dt, horizon, n, target, options in rows:
        r = run_row(model, params, dim, dt, horizon, n, args.steps, args.sigma if dim == 3 else 0.1, args.seed, dict(options))
        share = f"{100 * r['fallbacks'] / r['solves']:.1f}%"
        share_in = f"{100 * r['fallbacks_in_cell'] / max(r['in_cell'], 1):.1f}%"
        brake = f"{100 * r['brakes'] / r['solves']:.1f}%"
        print(f"{label:32s} {r['solves']:6d} {share:>8s} {share_in:>9s} {brake:>6s} {r['median']:9.2f} {r['p95']:9.2f} "
              f"{r['cpu_median']:8.2f} {r['cpu_p95']:8.2f} {target:7.1f}  {r['median'] / target:.2f}")


def run_row(model, params, dim, dt, horizon, n, steps, sigma, seed, options):
    """One row; ``legacy`` runs IPOPT without the SQP recovery (braking when it fails), as before issue 10."""
    if not options.pop("legacy", False):
        return run(model, params, dim, dt, horizon, n, steps, sigma, seed=seed, **options)
    original = BuavcMPC._condensed_sqp
    BuavcMPC._condensed_sqp = lambda self: None
    try:
        return run(model, params, dim, dt, horizon, n, steps, sigma, seed=seed, **options)
    finally:
        BuavcMPC._condensed_sqp = original


if __name__ == "__main__":
    main()
