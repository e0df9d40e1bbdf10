"""Throughput of the grid search (Yang 2017) on the Fig. 7 area, per algorithm.

Prints runs per CPU second (process time: the work done, whatever else runs on the machine; no store) for 1, 5 and 13 robots and each algorithm:
``run_search`` alone (no arrays recorded), ``simulate`` (the recorded run of the family
contract), one sweep task (the task function of the shipped ``search_fig7`` sweep: the
grid point's spec, validated once per process, then ``simulate`` and ``summary``: what
every run of the Fig. 7 sweep does, store writes aside) and lockstep batches of ``--batch`` runs (``run_search_batch``). With
``--full-estimate`` it projects the single-core time of the 26,000-run Fig. 7 sweep
(500 runs × 13 robot counts × 4 algorithms) from sweep tasks of every robot count.

    python benchmarks/search.py [--runs 25] [--batch 25] [--full-estimate]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

from robofleet import load_scenario, simulate
from robofleet.core.rng import spawn_seeds
from robofleet.experiments import plan_sweep
from robofleet.experiments.reproductions.search import FIG7_ALGORITHMS
from robofleet.search.simulation import build_problem, run_search, run_search_batch
from robofleet.search.spec import LABELS

FIG7 = "search/fig7"
FIG7_ROBOTS = tuple(range(1, 14))


def per_run(fn, seeds: list[int]) -> float:
    """CPU seconds per call of ``fn(seed)`` over ``seeds``."""
    start = time.process_time()
    for seed in seeds:
        fn(seed)
    return (time.process_time() - start) / len(seeds)


def sweep_task_seconds(algorithm, n_robots: int, seeds: list[int]) -> float:
    """Seconds per task of the shipped ``search_fig7`` sweep (its plan's task function)."""
    task = plan_sweep("search_fig7").fn
    return per_run(lambda s: task({"seed": s, "algorithm": algorithm.value, "robots.count": n_robots}), seeds)


def measure_batched(spec, algorithm, seeds: list[int], batch: int) -> float:
    """CPU seconds per run when ``seeds`` run in lockstep batches of ``batch``."""
    start = time.process_time()
    for first in range(0, len(seeds), batch):
        chunk = seeds[first:first + batch]
        run_search_batch([build_problem(spec, s) for s in chunk], algorithm, chunk)
    return (time.process_time() - start) / len(seeds)


def measure(algorithm, n_robots: int, runs: int, batch: int) -> dict[str, float]:
    """CPU seconds per run alone, recorded, as a sweep task and batched; mean steps per run."""
    spec = load_scenario(FIG7, {"robots.count": n_robots, "algorithm": algorithm.value})
    run_search(build_problem(spec, 0), algorithm, 0)  # warm caches (grid, sensing tables, coverage probe)
    seeds = spawn_seeds(99, runs)
    steps = [run_search(build_problem(spec, s), algorithm, s).steps for s in seeds]
    return {
        "steps": sum(steps) / runs,
        "alone": per_run(lambda s: run_search(build_problem(spec, s), algorithm, s), seeds),
        "recorded": per_run(lambda s: simulate(spec, seed=s), seeds),
        "task": sweep_task_seconds(algorithm, n_robots, seeds),
        "batched": measure_batched(spec, algorithm, seeds, batch),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=25)
    parser.add_argument("--batch", type=int, default=25)
    parser.add_argument("--full-estimate", action="store_true", help="time every robot count 1..13 to project the sweep")
    args = parser.parse_args()
    print(f"python {platform.python_version()}, {platform.machine()}; {args.runs} runs per point, batches of {args.batch}; "
          f"runs per CPU second; load average {os.getloadavg()[0]:.1f}")
    print(f"{'algorithm':<12} {'robots':>6} {'steps/run':>10} {'alone/s':>8} {'simulate/s':>11} {'tasks/s':>8} {'batched/s':>10}")
    for alg in FIG7_ALGORITHMS:
        for n in (1, 5, 13):
            m = measure(alg, n, args.runs, args.batch)
            print(f"{LABELS[alg]:<12} {n:>6} {m['steps']:>10.1f} {1 / m['alone']:>8.1f} {1 / m['recorded']:>11.1f} "
                  f"{1 / m['task']:>8.1f} {1 / m['batched']:>10.1f}")
    if args.full_estimate:
        total = sum(sweep_task_seconds(alg, n, spawn_seeds(99, args.runs)) * 500 for alg in FIG7_ALGORITHMS for n in FIG7_ROBOTS)
        print(f"projected Fig. 7 sweep (26,000 sweep tasks, store writes aside): {total:.0f} CPU s, "
              f"~{total / 2:.0f} s on two idle cores")


if __name__ == "__main__":
    main()
