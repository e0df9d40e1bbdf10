"""Per-task overhead of each executor of robofleet.experiments, for a trivial task.

Prints, per executor, the throughput of executing tasks alone (no store) and of
``run_tasks`` (execution + one atomic Parquet file per task), each with the fixed
start-up cost (process pool / Dask LocalCluster) separated from the per-task cost:
``start-up ≈ T(1)``, ``per task ≈ (T(N) − T(1)) / (N − 1)``.

    python benchmarks/experiments_overhead.py [--tasks 300] [--workers 2]
"""

from __future__ import annotations

import argparse
import tempfile
import time

from robofleet.experiments import run_tasks
from robofleet.experiments._selftest import trivial
from robofleet.experiments.executors import execute


def tasks(n: int, tag: str) -> list[dict]:
    return [{"run_id": f"{tag}-{i}", "seed": i} for i in range(n)]


def time_execute(executor: str, n: int, workers: int) -> float:
    start = time.perf_counter()
    for _ in execute(trivial, tasks(n, "x"), executor, None, workers):
        pass
    return time.perf_counter() - start


def time_run_tasks(executor: str, n: int, workers: int) -> float:
    with tempfile.TemporaryDirectory() as store:
        start = time.perf_counter()
        run_tasks(trivial, tasks(n, "x"), store, executor=executor, workers=workers, progress=False)
        return time.perf_counter() - start


def report(label: str, t1: float, tn: float, n: int) -> None:
    per_task = (tn - t1) / (n - 1)
    print(f"| {label} | {t1 * 1e3:8.1f} | {per_task * 1e3:8.3f} | {1 / per_task:9.0f} | {n / tn:9.0f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, default=300)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    n, workers = args.tasks, args.workers
    print(f"trivial task, N = {n}, workers = {workers}")
    print("| executor | start-up T(1) ms | per task ms | tasks/s (marginal) | tasks/s (N incl. start-up) |")
    print("|---|---:|---:|---:|---:|")
    for executor in ("serial", "process", "dask"):
        report(f"{executor}, execute only", time_execute(executor, 1, workers), time_execute(executor, n, workers), n)
        report(f"{executor}, run_tasks + store", time_run_tasks(executor, 1, workers), time_run_tasks(executor, n, workers), n)


if __name__ == "__main__":
    main()
