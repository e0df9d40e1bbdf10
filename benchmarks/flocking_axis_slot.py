"""Formation of patterns whose on-axis slot is not the nearest to the leader: prints
figures, asserts nothing.

For a 7-follower diamond whose single on-axis slot is the farthest from the leader, runs
the basic algorithm (Gervasi & Prencipe 2001, Algorithm 1) with the paper's ranking and
with ``algorithm.ranking: axis_slot_nearest`` (beyond the paper) on the same seeds, in
the paper's setting (ASYNC, random starts in 512 × 512, follower speeds U(0.5, 5), leader
with random turns), and prints per ranking the runs formed and kept (``success``), the
median convergence time of Δ_e and the median number of slot changes.

Run: ``python benchmarks/flocking_axis_slot.py [--seeds 10] [--duration 1500]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from robofleet import load_scenario, simulate

DIAMOND = [[-40, 30], [-40, -30], [-80, 60], [-80, -60], [-120, 30], [-120, -30], [-160, 0]]


def diamond_spec(ranking: str, duration: float, scheduler: str):
    return load_scenario({"family": "flocking", "name": "diamond", "pattern": {"kind": "points", "points": DIAMOND},
                          "scheduler": {"kind": scheduler}, "algorithm": {"kind": "basic", "ranking": ranking},
                          "duration": duration})


def measure(ranking: str, seeds: int, duration: float, scheduler: str) -> dict:
    spec = diamond_spec(ranking, duration, scheduler)
    t0 = time.perf_counter()
    rows = [simulate(spec, seed=s).results for s in range(seeds)]
    return {"formed": sum(bool(r["success"]) for r in rows), "runs": seeds,
            "median_convergence": float(np.nanmedian([r["convergence_time_e"] for r in rows]))
            if any(np.isfinite(r["convergence_time_e"]) for r in rows) else float("nan"),
            "median_slot_changes": float(np.median([r["slot_changes"] for r in rows])),
            "seconds_per_run": (time.perf_counter() - t0) / seeds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="runs per ranking (seeds 0..N-1)")
    parser.add_argument("--duration", type=float, default=1500.0, help="simulated time units per run")
    parser.add_argument("--scheduler", default="async", choices=["async", "ssync", "fsync"])
    args = parser.parse_args()
    print(f"7-follower diamond, axis slot farthest from the leader; {args.scheduler}, duration {args.duration:g}")
    for ranking in ("paper", "axis_slot_nearest"):
        m = measure(ranking, args.seeds, args.duration, args.scheduler)
        print(f"ranking {ranking:<18} formed {m['formed']}/{m['runs']}  median convergence of Δ_e "
              f"{m['median_convergence']:.0f}  median slot changes {m['median_slot_changes']:.0f}  "
              f"({m['seconds_per_run']:.1f} s per run)")


if __name__ == "__main__":
    main()
