"""Closed-loop 3-D B-UAVC runs with each quadrotor MPC solver (issue 10, item 4).

Runs ``scenarios/avoidance/quadrotors_3d.yaml`` and ``heterogeneous.yaml`` for every seed ×
noise level × solver configuration (``ipopt``; ``rti``; ``rti`` with ``terminal_speed``),
the robots' σ set to the given level, and prints one JSON line per run, then per group:
successes, runs with a contact, contact steps, mean MPC fallback share, mean travel time.

Usage: ``python benchmarks/mpc_3d.py [--seeds 0 20] [--sigmas 0.05] [--scenarios quadrotors_3d heterogeneous]``.
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

import robofleet

CONFIGS = [{"solver": "ipopt"}, {"solver": "rti"}, {"solver": "rti", "terminal_speed": 0.3}]
KEYS = ["success", "arrived", "collisions", "obstacle_collisions", "collision_steps", "mean_travel_time", "mpc_fallback_share"]


def run(base: dict, sigma: float, seed: int, config: dict) -> dict:
    mapping = copy.deepcopy(base)
    for team in mapping["teams"]:
        team["sigma"] = sigma
        if team["model"].get("controller") == "mpc":
            team["model"].setdefault("mpc", {}).update(config)
    t0 = time.perf_counter()
    summary = robofleet.simulate(robofleet.load_scenario(mapping), seed=seed).summary()
    return {"wall": round(time.perf_counter() - t0, 1), **{k: summary.get(k) for k in KEYS}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs=2, default=[0, 20])
    parser.add_argument("--sigmas", type=float, nargs="+", default=[0.05])
    parser.add_argument("--scenarios", nargs="+", default=["quadrotors_3d", "heterogeneous"])
    args = parser.parse_args()
    groups = collections.defaultdict(list)
    for name in args.scenarios:
        base = yaml.safe_load(Path(f"scenarios/avoidance/{name}.yaml").read_text())
        for sigma in args.sigmas:
            for seed in range(*args.seeds):
                for config in CONFIGS:
                    row = run(base, sigma, seed, config)
                    print(json.dumps({"scenario": name, "sigma": sigma, "seed": seed, "config": config, **row}), flush=True)
                    groups[(name, sigma, json.dumps(config))].append(row)
    for (name, sigma, config), rows in groups.items():
        print(f"{name} σ={sigma} {config}: runs {len(rows)}, success {sum(r['success'] for r in rows)}, "
              f"runs with contact {sum(r['collision_steps'] > 0 for r in rows)}, contact steps {sum(r['collision_steps'] for r in rows)}, "
              f"fallback share {np.mean([r['mpc_fallback_share'] for r in rows]):.3f}, "
              f"travel {np.nanmean([r['mean_travel_time'] or np.nan for r in rows]):.2f} s")


if __name__ == "__main__":
    main()
