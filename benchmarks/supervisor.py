"""Decision time of the online RMTRACK supervisor (``robofleet.coordination.Supervisor``).

A synthetic collision-free plan of ``--robots`` robots (straight lines across a square,
each robot delayed just enough to avoid the earlier ones: ``synthetic_plan`` of
``benchmarks/coordination.py``) is executed in closed loop: every tick each robot
attempts its next step if its last answer allows it (disturbed with probability
``--p``), and reports its progress; reports arrive after 0–``--max-delay`` ticks, so out
of order. Each arriving report is fed to the supervisor and answered at once; the time
of ``report()`` + ``answer()`` is recorded per report. Variants: RMTRACK, RMTRACK+TFF and
RMTRACK+TFA with the segment-graph check.

Prints figures; asserts nothing.

Run:  nice python benchmarks/supervisor.py [--robots 100] [--max-ticks 4000]
"""

from __future__ import annotations

import argparse
import heapq
import importlib.util
import time
from pathlib import Path

import numpy as np

from robofleet.coordination import Supervisor


def synthetic_plan(n: int, seed: int):
    """``synthetic_plan`` of the coordination benchmark (collision-free straight lines)."""
    spec = importlib.util.spec_from_file_location("coordination_benchmark", Path(__file__).with_name("coordination.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.synthetic_plan(n, np.random.default_rng(seed))


def closed_loop(sup: Supervisor, p: float, max_delay: int, max_ticks: int, seed: int) -> tuple[np.ndarray, int, bool]:
    """Run until every robot finishes (or ``max_ticks``); per-report decision times
    ``(reports, 2)`` [s]: wall clock and the thread's CPU time (which a busy machine's
    scheduling does not inflate)."""
    rng = np.random.default_rng(seed)
    traj = sup.traj
    n = traj.n_robots
    x, allowed, inbox, times = np.zeros(n, np.intp), np.zeros(n, np.intp), [], []
    for t in range(max_ticks):
        for i in range(n):
            heapq.heappush(inbox, (t + int(rng.integers(0, max_delay + 1)), float(rng.random()), i, int(x[i])))
        while inbox and inbox[0][0] <= t:
            _, _, robot, step = heapq.heappop(inbox)
            t0, c0 = time.perf_counter(), time.thread_time()
            sup.report(robot, progress=step)
            answer = sup.answer(robot)
            times.append((time.perf_counter() - t0, time.thread_time() - c0))
            allowed[robot] = answer.until
        x = x + ((x < allowed) & (rng.random(n) >= p))
        if np.all(x >= traj.lengths):
            return np.asarray(times), t + 1, True
    return np.asarray(times), max_ticks, False


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=100)
    ap.add_argument("--p", type=float, default=0.3, help="disturbance probability per attempted step")
    ap.add_argument("--max-delay", type=int, default=5, help="largest report delay [ticks]")
    ap.add_argument("--max-ticks", type=int, default=4000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    t0 = time.perf_counter()
    traj = synthetic_plan(args.robots, args.seed)
    plan_seconds = time.perf_counter() - t0
    print(f"## supervisor decision time per report: {args.robots} robots, steps per robot "
          f"{int(traj.lengths.min())}–{int(traj.lengths.max())} (plan built in {plan_seconds:.1f} s), "
          f"p = {args.p}, reports late by 0–{args.max_delay} ticks")
    print("| variant | obstacles | set-up [s] | reports | mean [µs] | median [µs] | p90 [µs] | p99 [µs] | p99 CPU [µs] | max [ms] | flips kept / refused | ticks | finished |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for method in ("rmtrack", "tff", "tfa"):
        t0 = time.perf_counter()
        sup = Supervisor(traj, method=method, deadlock_check=True, probability=args.p)
        setup = time.perf_counter() - t0
        times, ticks, finished = closed_loop(sup, args.p, args.max_delay, args.max_ticks, args.seed)
        wall, cpu = times[:, 0], times[:, 1]
        us = np.percentile(wall, [50, 90, 99]) * 1e6
        stats = sup.stats
        name = "RMTRACK" if method == "rmtrack" else f"RMTRACK+{method.upper()} (checked)"
        print(f"| {name} | {sup.space.n_obstacles} | {setup:.2f} | {len(wall)} | {wall.mean() * 1e6:.0f} | {us[0]:.0f} | {us[1]:.0f} | {us[2]:.0f} | "
              f"{np.percentile(cpu, 99) * 1e6:.0f} | {wall.max() * 1e3:.1f} | {stats['flips']} / {stats['refused']} | {ticks} | {finished} |", flush=True)


if __name__ == "__main__":
    main()
