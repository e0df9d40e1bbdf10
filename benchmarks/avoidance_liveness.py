"""Liveness of B-UAVC: success, arrivals, travel time and contacts over many seeds.

For each shipped 2-D avoidance scenario (``scenarios/avoidance/*.yaml`` without
``space3d``) runs ``--seeds`` seeds with the shipped step budget, and ``--random``
scenarios of :func:`robofleet.avoidance.random_scenarios.random_scenario` (8–16 robots,
random antipodal swap, random convex obstacles; one seed each). Prints, per scenario,
success with its Clopper–Pearson 95 % interval, the share of robots that arrived, the
mean travel time over successful runs, contacts and the per-step contact rate's 95 %
upper bound (next to δ). ``--liveness on|off|spec`` overrides the ``liveness:`` block.

Run: ``python benchmarks/avoidance_liveness.py [--seeds 20] [--random 20] [--scenarios ten_boxes ...] [--liveness off] [--budget-factor 4]``
"""

from __future__ import annotations

import argparse
import glob
import os
import time

import numpy as np
import yaml
from scipy.stats import beta

import robofleet
from robofleet.avoidance.random_scenarios import random_scenario

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval of ``k`` successes in ``n`` trials (Clopper & Pearson 1934)."""
    a = (1 - level) / 2
    lo = beta.ppf(a, k, n - k + 1) if k > 0 else 0.0
    hi = beta.ppf(1 - a, k + 1, n - k) if k < n else 1.0
    return float(lo), float(hi)


def shipped_mappings(names: list[str] | None) -> dict[str, dict]:
    """The shipped 2-D scenarios as mappings, by name."""
    out = {}
    for path in sorted(glob.glob(os.path.join(ROOT, "scenarios", "avoidance", "*.yaml"))):
        with open(path) as fh:
            data = yaml.safe_load(fh)
        name = os.path.splitext(os.path.basename(path))[0]
        if data.get("space3d") is None and (not names or name in names):
            out[name] = data
    return out


def with_liveness(mapping: dict, mode: str, budget_factor: float = 1.0) -> dict:
    """``mapping`` with its ``liveness`` block switched on/off (``spec`` keeps it) and its
    step budget multiplied by ``budget_factor``."""
    out = {**mapping, "max_steps": int(round(budget_factor * mapping.get("max_steps", 500)))}
    if mode != "spec":
        out["liveness"] = {**mapping.get("liveness", {}), "enabled": mode == "on"}
    return out


def run(mapping: dict, seed: int) -> dict:
    """The summary of one run (cells not recorded)."""
    spec = robofleet.load_scenario({**mapping, "record_cells": False})
    trace = robofleet.simulate(spec, seed=seed)
    positions = trace.arrays["positions"]
    return {**trace.results, "robot_steps": int(positions.shape[0] * positions.shape[1])}


def summarise(label: str, results: list[dict], delta: float) -> str:
    """One table row of a batch of runs."""
    n = len(results)
    k = sum(bool(r["success"]) for r in results)
    lo, hi = clopper_pearson(k, n)
    arrived = np.mean([r["arrived"] for r in results])
    times = [r["mean_travel_time"] for r in results if r["success"]]
    contacts = sum(int(r["collision_steps"]) for r in results)
    steps = sum(r["robot_steps"] for r in results)
    rate_hi = clopper_pearson(contacts, max(steps, 1))[1] if steps else float("nan")
    t = f"{np.mean(times):.1f}" if times else "—"
    return (f"| {label} | {n} | {100 * k / n:.0f} % [{100 * lo:.0f}, {100 * hi:.0f}] | {100 * arrived:.0f} % | {t} | "
            f"{contacts} | {rate_hi:.1e} (δ = {delta}) |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="seeds per shipped scenario")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--random", type=int, default=20, help="random scenarios (seeds first-seed…)")
    ap.add_argument("--scenarios", nargs="*", default=None, help="shipped scenario names (default: all 2-D)")
    ap.add_argument("--liveness", choices=["on", "off", "spec"], default="spec")
    ap.add_argument("--budget-factor", type=float, default=1.0, help="multiply every step budget (1 = as shipped)")
    args = ap.parse_args()
    print("| scenario | runs | success [CP 95 %] | arrived | mean travel time of successes [s] | contact steps | robot-step contact rate, 95 % upper |")
    print("|---|---:|---:|---:|---:|---:|---|")
    t0 = time.perf_counter()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    for name, mapping in shipped_mappings(args.scenarios).items():
        m = with_liveness(mapping, args.liveness, args.budget_factor)
        print(summarise(name, [run(m, s) for s in seeds], mapping.get("delta", 0.1)), flush=True)
    if args.random:
        rnd = range(args.first_seed, args.first_seed + args.random)
        results = [run(with_liveness(random_scenario(s), args.liveness, args.budget_factor), s) for s in rnd]
        print(summarise(f"random (seeds {rnd.start}–{rnd.stop - 1})", results, 0.1), flush=True)
    print(f"wall time: {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
