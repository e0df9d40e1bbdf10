"""Throughput of the grid search (paper 002) on the Fig. 7 area, per algorithm.

Prints runs per second (one core, no store) for 1, 5 and 13 robots and each algorithm,
the time per simulated step, and the projected single-core time of the 26,000-run Fig. 7
sweep (500 runs × 13 robot counts × 4 algorithms, estimated from ``--runs`` runs per point
of every robot count).

    python benchmarks/search.py [--runs 20] [--full-estimate]
"""

from __future__ import annotations

import argparse
import platform
import time

from robofleet import load_scenario
from robofleet.search.reproduce import FIG7_ALGORITHMS, FIG7_ROBOTS, run_seeds, shipped_scenario
from robofleet.search.scenario import build_problem
from robofleet.search.simulation import LABELS, run_search


def measure(algorithm, n_robots: int, runs: int) -> tuple[float, float]:
    """(seconds per run, mean simulated steps per run) over ``runs`` seeded runs."""
    spec = load_scenario(shipped_scenario("fig7.yaml"), {"robots.count": n_robots, "algorithm": algorithm.value,
                                                         "require_guarantee": False})
    run_search(build_problem(spec, 0), algorithm, 0)  # warm caches (grid, sensing tables)
    steps = 0
    start = time.perf_counter()
    for seed in run_seeds(99, 0, runs):
        steps += run_search(build_problem(spec, seed), algorithm, seed).results["n_steps"]
    return (time.perf_counter() - start) / runs, steps / runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--full-estimate", action="store_true", help="time every robot count 1..13 to project the sweep")
    args = parser.parse_args()
    print(f"python {platform.python_version()}, {platform.machine()}; {args.runs} runs per point")
    print(f"{'algorithm':<12} {'robots':>6} {'runs/s':>9} {'ms/run':>8} {'steps/run':>10} {'us/step':>8}")
    for alg in FIG7_ALGORITHMS:
        for n in (1, 5, 13):
            sec, steps = measure(alg, n, args.runs)
            print(f"{LABELS[alg]:<12} {n:>6} {1 / sec:>9.1f} {sec * 1e3:>8.2f} {steps:>10.1f} {sec / max(steps, 1) * 1e6:>8.1f}")
    if args.full_estimate:
        total = sum(measure(alg, n, args.runs)[0] for alg in FIG7_ALGORITHMS for n in FIG7_ROBOTS) * 500
        print(f"projected Fig. 7 sweep (26,000 runs): {total:.0f} s on one core, ~{total / 2:.0f} s on two workers")


if __name__ == "__main__":
    main()
