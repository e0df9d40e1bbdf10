"""Closed-loop 3-D B-UAVC runs with the quadrotor MPC (issue 10, item 4).

Runs ``scenarios/avoidance/quadrotors_3d.yaml`` and ``heterogeneous.yaml`` (the mixed
ground/air team) with their shipped step budgets for every seed × noise level × solver
configuration — a noise level multiplies every team's σ of the file (``--scales``, default
×0.5, ×1, ×2; ``--sigmas`` sets every team's σ instead; the obstacles keep their σ_o) —
and prints one JSON line per run, then one table row per group: runs, successes (with
the two-sided Clopper–Pearson 95 % interval), runs with a contact (with the one-sided
Clopper–Pearson 95 % upper bound of the per-run contact probability), contact steps, the
MPC's share of robot-steps without an in-cell plan (``fallback``: ``mpc_status`` 1 over 0
and 1), of those the share whose estimate lay in its own cell, the share that had to
brake (no plan at all), the per-robot-step solve time (median and 95th percentile of the
CPU time of ``BuavcMPC.plan``), and the mean travel time.

Usage: ``python benchmarks/mpc_3d.py [--seeds 0 20] [--scales 0.5 1 2 | --sigmas 0.02 0.05]
[--scenarios quadrotors_3d heterogeneous] [--configs rti ipopt]``.
"""

from __future__ import annotations

import argparse
import collections
import copy
import json
import time
from pathlib import Path

import numpy as np
import yaml
from _machine import machine
from scipy.stats import beta

import robofleet
from robofleet.avoidance.mpc import BuavcMPC

CONFIGS = {"rti": {"solver": "rti"}, "rti_no_band": {"solver": "rti", "noise_band": 0.0}, "ipopt": {"solver": "ipopt"}}
KEYS = ["success", "arrived", "collisions", "obstacle_collisions", "collision_steps", "mean_travel_time", "mpc_fallback_share"]


class PlanTimer:
    """Wraps :meth:`BuavcMPC.plan` to record each call's CPU time and whether it braked."""

    def __init__(self):
        self.cpu: list[float] = []
        self.brakes = 0
        self._plan = BuavcMPC.plan

    def __enter__(self):
        timer = self

        def timed(mpc, *args, **kwargs):
            c0 = time.thread_time()
            result = timer._plan(mpc, *args, **kwargs)
            timer.cpu.append(time.thread_time() - c0)
            timer.brakes += result.control is None
            return result

        BuavcMPC.plan = timed
        return self

    def __exit__(self, *exc):
        BuavcMPC.plan = self._plan


def run(base: dict, noise: tuple[str, float], seed: int, config: dict) -> dict:
    """One run of scenario ``base`` with every team's σ set (``("sigma", σ)``) or scaled
    (``("scale", k)``), the MPC teams' solver configured by ``config``."""
    mapping = copy.deepcopy(base)
    kind, level = noise
    for team in mapping["teams"]:
        team["sigma"] = level if kind == "sigma" else level * team["sigma"]
        if team["model"].get("controller") == "mpc":
            team["model"].setdefault("mpc", {}).update(config)
    t0 = time.perf_counter()
    with PlanTimer() as timer:
        trace = robofleet.simulate(robofleet.load_scenario(mapping), seed=seed)
    summary = trace.summary()
    status, inside = trace.arrays["mpc_status"], trace.arrays["estimate_in_cell"]
    solving = (status == 0) | (status == 1)
    return {"wall": round(time.perf_counter() - t0, 1), **{k: summary.get(k) for k in KEYS},
            "solves": int(solving.sum()), "fallbacks": int((status == 1).sum()),
            "fallbacks_in_cell": int(((status == 1) & inside).sum()), "brakes": timer.brakes,
            "cpu_ms": [round(1e3 * c, 3) for c in timer.cpu]}


def clopper_pearson_upper(k: int, n: int, level: float = 0.95) -> float:
    """One-sided ``level`` upper bound of a binomial probability after ``k`` events in ``n`` trials."""
    return 1.0 if k >= n else float(beta.ppf(level, k + 1, n - k))


def clopper_pearson_interval(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` interval of a binomial probability after ``k`` successes in ``n`` trials."""
    tail = (1.0 - level) / 2
    low = 0.0 if k == 0 else float(beta.ppf(tail, k, n - k + 1))
    high = 1.0 if k == n else float(beta.ppf(1.0 - tail, k + 1, n - k))
    return low, high


def report(name: str, noise: str, config: str, rows: list[dict]) -> str:
    runs, contact = len(rows), sum(r["collision_steps"] > 0 for r in rows)
    wins = sum(r["success"] for r in rows)
    low, high = clopper_pearson_interval(wins, runs)
    solves, fallbacks = sum(r["solves"] for r in rows), sum(r["fallbacks"] for r in rows)
    cpu = np.concatenate([r["cpu_ms"] for r in rows])
    travel = [r["mean_travel_time"] for r in rows if r["mean_travel_time"] is not None]
    return (f"| {name} | {noise} | {config} | {runs} | {wins} [{100 * low:.0f}–{100 * high:.0f} %] | {contact} "
            f"(≤ {clopper_pearson_upper(contact, runs):.3f}) | {sum(r['collision_steps'] for r in rows)} | "
            f"{100 * fallbacks / max(solves, 1):.2f} % | {100 * sum(r['fallbacks_in_cell'] for r in rows) / max(solves, 1):.2f} % | "
            f"{100 * sum(r['brakes'] for r in rows) / max(solves, 1):.2f} % | {np.median(cpu):.2f} | {np.percentile(cpu, 95):.2f} | "
            f"{np.mean(travel) if travel else float('nan'):.2f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs=2, default=[0, 20])
    levels = parser.add_mutually_exclusive_group()
    levels.add_argument("--scales", type=float, nargs="+", default=[0.5, 1.0, 2.0], help="multiples of every team's σ")
    levels.add_argument("--sigmas", type=float, nargs="+", help="every team's σ")
    parser.add_argument("--scenarios", nargs="+", default=["quadrotors_3d", "heterogeneous"])
    parser.add_argument("--configs", nargs="+", default=["rti"], choices=sorted(CONFIGS))
    args = parser.parse_args()
    print(machine())
    groups = collections.defaultdict(list)
    for name in args.scenarios:
        base = yaml.safe_load(Path(f"scenarios/avoidance/{name}.yaml").read_text())
        noises = [("sigma", s) for s in args.sigmas] if args.sigmas else [("scale", k) for k in args.scales]
        for noise in noises:
            label = f"σ = {noise[1]}" if noise[0] == "sigma" else f"σ × {noise[1]:g}"
            for seed in range(*args.seeds):
                for config in args.configs:
                    row = run(base, noise, seed, CONFIGS[config])
                    brief = {k: v for k, v in row.items() if k != "cpu_ms"}
                    print(json.dumps({"scenario": name, "noise": label, "seed": seed, "config": config, **brief}, ensure_ascii=False), flush=True)
                    groups[(name, label, config)].append(row)
    print("| scenario | noise | solver | runs | success [CP 95 %] | runs with contact (CP 95 % upper) | contact steps | fallback | "
          "fallback, estimate in cell | brake | solve CPU median [ms] | solve CPU p95 [ms] | mean travel time [s] |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (name, noise, config), rows in groups.items():
        print(report(name, noise, config, rows))
    runs = [r for rows in groups.values() for r in rows]
    contact = sum(r["collision_steps"] > 0 for r in runs)
    print(f"all groups: {len(runs)} runs, {contact} with contact, Clopper–Pearson 95 % upper bound "
          f"{clopper_pearson_upper(contact, len(runs)):.4f}")


if __name__ == "__main__":
    main()
