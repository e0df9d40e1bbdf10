"""Throughput of the grid search (paper 002) on the Fig. 7 area, per algorithm.

Prints runs per second on one core (no store) for 1, 5 and 13 robots and each algorithm,
run one at a time (``run_search``) and as lockstep batches of ``--batch`` runs
(``run_search_batch``, what the Fig. 7 tasks do), the speed-up of batching, and, with
``--full-estimate``, the projected single-core time of the 26,000-run Fig. 7 sweep
(500 runs × 13 robot counts × 4 algorithms) from batched runs of every robot count.

    python benchmarks/search.py [--runs 25] [--batch 25] [--full-estimate]
"""

from __future__ import annotations

import argparse
import platform
import time

from robofleet import load_scenario
from robofleet.scenarios import shipped_scenario
from robofleet.search.reproduce import FIG7_ALGORITHMS, FIG7_ROBOTS, run_seeds
from robofleet.search.scenario import build_problem
from robofleet.search.simulation import LABELS, run_search, run_search_batch


def measure(algorithm, n_robots: int, runs: int, batch: int) -> tuple[float, float, float]:
    """(seconds per run alone, seconds per run in batches, mean simulated steps per run)."""
    spec = load_scenario(shipped_scenario("search", "fig7.yaml"), {"robots.count": n_robots, "algorithm": algorithm.value,
                                                         "require_guarantee": False})
    run_search(build_problem(spec, 0), algorithm, 0)  # warm caches (grid, sensing tables)
    seeds = run_seeds(99, 0, runs)
    steps = 0
    start = time.perf_counter()
    for seed in seeds:
        steps += run_search(build_problem(spec, seed), algorithm, seed).results["n_steps"]
    alone = (time.perf_counter() - start) / runs
    return alone, measure_batched(spec, algorithm, seeds, batch), steps / runs


def measure_batched(spec, algorithm, seeds: list[int], batch: int) -> float:
    """Seconds per run when ``seeds`` run in lockstep batches of ``batch``."""
    start = time.perf_counter()
    for first in range(0, len(seeds), batch):
        chunk = seeds[first:first + batch]
        run_search_batch([build_problem(spec, s) for s in chunk], algorithm, chunk)
    return (time.perf_counter() - start) / len(seeds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=25)
    parser.add_argument("--batch", type=int, default=25)
    parser.add_argument("--full-estimate", action="store_true", help="time every robot count 1..13 to project the sweep")
    args = parser.parse_args()
    print(f"python {platform.python_version()}, {platform.machine()}; {args.runs} runs per point, batches of {args.batch}")
    print(f"{'algorithm':<12} {'robots':>6} {'steps/run':>10} {'runs/s alone':>13} {'runs/s batched':>15} {'speed-up':>9}")
    for alg in FIG7_ALGORITHMS:
        for n in (1, 5, 13):
            alone, batched, steps = measure(alg, n, args.runs, args.batch)
            print(f"{LABELS[alg]:<12} {n:>6} {steps:>10.1f} {1 / alone:>13.1f} {1 / batched:>15.1f} {alone / batched:>8.1f}x")
    if args.full_estimate:
        total = 0.0
        for alg in FIG7_ALGORITHMS:
            for n in FIG7_ROBOTS:
                spec = load_scenario(shipped_scenario("search", "fig7.yaml"), {"robots.count": n, "algorithm": alg.value})
                total += measure_batched(spec, alg, run_seeds(99, 0, args.runs), args.batch) * 500
        print(f"projected Fig. 7 sweep (26,000 runs, batched): {total:.0f} s on one core, ~{total / 2:.0f} s on two workers")


if __name__ == "__main__":
    main()
