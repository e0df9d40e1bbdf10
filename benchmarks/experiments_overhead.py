"""Per-task overhead of each executor of robofleet.experiments, and a real sweep.

1. A trivial task: per executor, the throughput of executing tasks alone (no store) and
   of ``run_tasks`` (execution + one atomic Parquet file per task), with the fixed start-up
   cost (process pool / Dask LocalCluster) separated from the per-task cost:
   ``start-up ≈ T(1)``, ``per task ≈ (T(N) − T(1)) / (N − 1)``, each T the best of 3.
2. A real sweep (``--scenario``, default the shipped circle swap, ``--runs`` seeds) on
   every executor: wall time, runs/s, speed-up over serial, and whether the rows are
   identical (timing columns aside). Each executor first runs a small warm-up sweep, so
   per-process imports and JIT compilation are not counted.

Dask runs use one LocalCluster started beforehand (its start-up time is printed
separately); serial and process figures include their own (small) start-up.

    python benchmarks/experiments_overhead.py [--tasks 300] [--workers 2] [--runs 8]
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time
from pathlib import Path

from robofleet.experiments import deterministic_columns, run_sweep, run_tasks
from robofleet.experiments._selftest import trivial
from robofleet.experiments.executors import execute


def tasks(n: int, tag: str) -> list[dict]:
    return [{"run_id": f"{tag}-{i}", "seed": i} for i in range(n)]


def time_execute(executor: str, n: int, workers: int, scheduler: str | None) -> float:
    start = time.perf_counter()
    for _ in execute(trivial, tasks(n, "x"), executor, scheduler, workers):
        pass
    return time.perf_counter() - start


def time_run_tasks(executor: str, n: int, workers: int, scheduler: str | None) -> float:
    with tempfile.TemporaryDirectory() as store:
        start = time.perf_counter()
        run_tasks(trivial, tasks(n, "x"), store, executor=executor, scheduler=scheduler, workers=workers, progress=False)
        return time.perf_counter() - start


def best_of(measure, *args, repeat: int = 3) -> float:
    """The minimum of ``repeat`` timings (the least disturbed by other load)."""
    return min(measure(*args) for _ in range(repeat))


def start_cluster(workers: int):
    """A Dask LocalCluster like the one ``executor="dask"`` starts; returns it and its start-up time."""
    import distributed

    start = time.perf_counter()
    cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR)
    return cluster, time.perf_counter() - start


def report(label: str, t1: float, tn: float, n: int) -> None:
    per_task = (tn - t1) / (n - 1)
    if per_task <= 0:  # start-up jitter larger than N tasks' cost
        marginal = "below noise | below noise"
    else:
        marginal = f"{per_task * 1e3:8.3f} | {1 / per_task:9.0f}"
    print(f"| {label} | {t1 * 1e3:8.1f} | {marginal} | {n / tn:9.0f} |")


def real_sweep(scenario: Path, runs: int, workers: int, address: str) -> None:
    print(f"\nreal sweep: {scenario.name} x {runs} seeds, workers = {workers}")
    print("| executor | wall s | runs/s | speed-up vs serial | rows identical to serial |")
    print("|---|---:|---:|---:|---|")
    sweep = {"scenario": str(scenario.resolve()), "seeds": runs, "root_seed": 0}
    warm_up = {**sweep, "seeds": 2 * workers, "root_seed": 1}
    reference, serial_seconds = None, None
    for executor in ("serial", "process", "dask"):
        scheduler = address if executor == "dask" else None
        with tempfile.TemporaryDirectory() as store:
            # imports and JIT compilation happen once per worker process: pay them first
            # (forked process workers inherit them from this process, Dask workers do not)
            run_sweep(warm_up, executor=executor, scheduler=scheduler, progress=False, workers=workers, out=Path(store) / "warm")
            start = time.perf_counter()
            frame = run_sweep(sweep, executor=executor, scheduler=scheduler, progress=False, workers=workers, out=store)
            seconds = time.perf_counter() - start
        columns = deterministic_columns(frame)
        if reference is None:
            reference, serial_seconds = frame[columns], seconds
        same = frame[columns].equals(reference)
        print(f"| {executor} | {seconds:.2f} | {runs / seconds:.2f} | {serial_seconds / seconds:.2f} | {same} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, default=300)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--scenario", type=Path, default=Path(__file__).resolve().parents[1] / "scenarios" / "avoidance" / "circle_swap.yaml")
    args = parser.parse_args()
    n, workers = args.tasks, args.workers
    cluster, cluster_seconds = start_cluster(workers)
    print(f"Dask LocalCluster start-up ({workers} worker processes): {cluster_seconds:.1f} s (not included below)")
    print(f"\ntrivial task, N = {n}, workers = {workers}")
    print("| executor | start-up T(1) ms | per task ms | tasks/s (marginal) | tasks/s (N incl. start-up) |")
    print("|---|---:|---:|---:|---:|")
    for executor in ("serial", "process", "dask"):
        scheduler = cluster.scheduler_address if executor == "dask" else None
        for label, measure in (("execute only", time_execute), ("run_tasks + store", time_run_tasks)):
            t1 = best_of(measure, executor, 1, workers, scheduler)
            report(f"{executor}, {label}", t1, best_of(measure, executor, n, workers, scheduler), n)
    real_sweep(args.scenario, args.runs, workers, cluster.scheduler_address)
    cluster.close()


if __name__ == "__main__":
    main()
