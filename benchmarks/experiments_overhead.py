"""What the sweep machinery of robofleet.experiments costs per run, against a bare loop.

1. Trivial tasks (``--tasks N``): per executor (serial, process, a thread pool, Dask),
   the time per task of executing alone (no store) and of ``run_tasks`` (execution, the
   journal, the batched Parquet store, reading the table back), with the fixed start-up
   cost separated: ``start-up ≈ T(1)``, ``per task ≈ (T(N) − T(1)) / (N − 1)``, each T
   the best of 3. Dask runs on one LocalCluster started beforehand.
2. Machinery overhead per run (``--runs K`` seeds per grid point of ``--sweep``, default a
   Fig. 7 grid): ``run_sweep`` on the serial executor against a bare loop of
   ``simulate(spec, seed).summary()`` over the same runs with the specs validated
   beforehand; the two alternate three times and the best of each is kept,
   ``overhead per run = (T_sweep − T_bare) / runs``, wall and CPU time, with the planning
   (once per sweep) shown apart; then the process executor's wall time.
3. ``--fig7``: the shipped Fig. 7 sweep (26,000 runs) on the process executor
   (``--workers``), with the store's file count and size, and the simulation alone
   estimated from a seeded sample of 300 runs (mean × 26,000 / workers).
4. ``--million N``: an N-run sweep of a trivial scenario (the test suite's toy family:
   one robot, one step), killed with SIGKILL after ``--kill-after`` seconds, then resumed
   to the end: planning time, runs stored at the kill, resume time, store size and files.

    python benchmarks/experiments_overhead.py [--tasks 20000] [--runs 20] [--workers 2] [--overhead-only]
    python benchmarks/experiments_overhead.py --fig7 [--workers 2]
    python benchmarks/experiments_overhead.py --million 1000000 --kill-after 300
"""

from __future__ import annotations

import argparse
import logging
import os
import random
import resource
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from _machine import machine

from robofleet import load_scenario, simulate
from robofleet.experiments import ResultStore, plan_sweep, run_sweep, run_tasks
from robofleet.experiments._selftest import trivial
from robofleet.experiments.executors import execute
from robofleet.experiments import sweep as sweep_module
from robofleet.experiments.sweep import expand_overrides

ROOT = Path(__file__).resolve().parents[1]
FIG7_GRID = {"scenario": "search/fig7", "grid": {"algorithm": ["lfp", "ru", "rule1", "proposed"],
                                                  "robots.count": list(range(1, 14))}, "root_seed": 2017}
TOY_SWEEP = {"scenario": {"family": "toy", "robots": {"n": 1}, "steps": 1}, "metrics": ["success", "final_spread"]}


def cpu_seconds() -> float:
    """CPU time of this process and of its finished children (worker processes): on a
    shared machine, the work done, whatever the load."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def tasks(n: int) -> list[dict]:
    return [{"run_id": f"x-{i}", "seed": i} for i in range(n)]


def time_execute(executor, n: int, workers: int, scheduler: str | None) -> float:
    start = time.perf_counter()
    for _ in execute(trivial, tasks(n), executor, scheduler, workers):
        pass
    return time.perf_counter() - start


def time_run_tasks(executor, n: int, workers: int, scheduler: str | None) -> float:
    with tempfile.TemporaryDirectory() as store:
        start = time.perf_counter()
        run_tasks(trivial, tasks(n), store, executor=executor, scheduler=scheduler, workers=workers, progress=False)
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


def trivial_tasks(n: int, workers: int) -> None:
    cluster, cluster_seconds = start_cluster(workers)
    print(f"Dask LocalCluster start-up ({workers} worker processes): {cluster_seconds:.1f} s (not included below)")
    print(f"\ntrivial task, N = {n}, workers = {workers}")
    print("| executor | start-up T(1) ms | per task µs | tasks/s (marginal) | tasks/s (N incl. start-up) |")
    print("|---|---:|---:|---:|---:|")
    threads = ThreadPoolExecutor(workers)
    for name, executor in (("serial", "serial"), ("process", "process"), ("thread pool", threads), ("dask", "dask")):
        scheduler = cluster.scheduler_address if name == "dask" else None
        for label, measure in (("execute only", time_execute), ("run_tasks + store", time_run_tasks)):
            t1 = best_of(measure, executor, 1, workers, scheduler)
            tn = best_of(measure, executor, n, workers, scheduler)
            per_task = (tn - t1) / (n - 1)
            marginal = f"{per_task * 1e6:8.1f} | {1 / per_task:9.0f}" if per_task > 0 else "below noise | below noise"
            print(f"| {name}, {label} | {t1 * 1e3:8.1f} | {marginal} | {n / tn:9.0f} |")
    threads.shutdown()
    cluster.close()


def bare_loop(plan) -> float:
    """``simulate(spec, seed).summary()`` over the plan's runs, the specs validated beforehand."""
    fixed = plan.fn.keywords["fixed"]
    source = plan.fn.keywords["source"] or plan.scenario
    specs = {}
    for task in plan.tasks:
        key = tuple(repr(task[k]) for k in plan.grid_keys)
        if key not in specs:
            specs[key] = load_scenario(source, overrides={**fixed, **expand_overrides({k: task[k] for k in plan.grid_keys})})
    start, cpu = time.perf_counter(), time.process_time()
    for task in plan.tasks:
        simulate(specs[tuple(repr(task[k]) for k in plan.grid_keys)], seed=task["seed"]).summary()
    return time.perf_counter() - start, time.process_time() - cpu


def time_sweep(sweep: dict, executor: str, workers: int) -> tuple[float, float]:
    """Wall and CPU seconds of ``run_sweep`` (CPU: this process and its worker processes)."""
    with tempfile.TemporaryDirectory() as store:
        start, cpu = time.perf_counter(), cpu_seconds()
        run_sweep(sweep, executor=executor, progress=False, workers=workers, out=store)
        return time.perf_counter() - start, cpu_seconds() - cpu


class StoredSummary:
    """Stands in for a trace: ``summary()`` returns a stored run's summary."""

    def __init__(self, summary: dict):
        self.stored = summary

    def summary(self) -> dict:
        return dict(self.stored)


def machinery_alone(sweep: dict, workers: int) -> tuple[float, float]:
    """Best of 3 (wall, CPU) of ``run_sweep`` on the serial executor with ``simulate``
    replaced by a lookup of each grid point's summary: what the machinery costs by itself
    (the grid points' specs are validated already: planning is timed apart)."""
    summaries: dict[int, dict] = {}
    real = sweep_module.simulate

    def stored(spec, seed=None, progress=False):
        if id(spec) not in summaries:
            summaries[id(spec)] = real(spec, seed=seed).summary()
        return StoredSummary(summaries[id(spec)])

    sweep_module.simulate = stored
    try:
        time_sweep(sweep, "serial", workers)  # fills the summaries (keyed by the cached spec objects)
        timings = [time_sweep(sweep, "serial", workers) for _ in range(3)]
    finally:
        sweep_module.simulate = real
    return min(t[0] for t in timings), min(t[1] for t in timings)


def machinery_overhead(runs: int, workers: int) -> None:
    sweep = {**FIG7_GRID, "seeds": runs}
    plan = plan_sweep(sweep)
    n = len(plan.tasks)
    time_sweep({**sweep, "seeds": 1, "root_seed": 1}, "serial", workers)  # warm-up: imports, compilation
    bare, swept, planned = [], [], []
    for _ in range(3):  # alternate, so slow phases of the shared machine hit both
        bare.append(bare_loop(plan))
        swept.append(time_sweep(sweep, "serial", workers))
        start, cpu = time.perf_counter(), time.process_time()
        sweep_module._specs.clear()  # plan as a fresh process does: every grid point validated
        plan_sweep(sweep)
        planned.append((time.perf_counter() - start, time.process_time() - cpu))
    best = {"bare": (min(b[0] for b in bare), min(b[1] for b in bare)), "sweep": (min(s[0] for s in swept), min(s[1] for s in swept)),
            "plan": (min(p[0] for p in planned), min(p[1] for p in planned))}
    print(f"\nmachinery overhead: Fig. 7 grid ({len(plan.combinations)} points) × {runs} seeds = {n} runs, serial, best of 3 each")
    print("| loop | wall s | wall ms per run | CPU s | CPU ms per run |")
    print("|---|---:|---:|---:|---:|")
    rows = [("bare loop: simulate(spec, seed).summary()", best["bare"]),
            ("run_sweep (plan, validate, run, store, read)", best["sweep"]),
            ("machinery overhead", tuple(s - b for s, b in zip(best["sweep"], best["bare"]))),
            ("of which planning (once per sweep: grid points validated, run ids)", best["plan"]),
            ("of which per run (overhead − planning)", tuple(s - b - p for s, b, p in zip(best["sweep"], best["bare"], best["plan"])))]
    machinery = machinery_alone(sweep, workers)
    rows.append(("machinery alone, measured directly (simulate replaced by a stored summary; specs validated already)", machinery))
    for label, (wall, cpu) in rows:
        print(f"| {label} | {wall:.3f} | {wall / n * 1e3:.3f} | {cpu:.3f} | {cpu / n * 1e3:.3f} |")
    process, process_cpu = time_sweep(sweep, "process", workers)
    print(f"process executor, {workers} workers: {process:.2f} s wall ({n / process:.0f} runs/s), {process_cpu:.2f} CPU s "
          f"(bare loop: {min(bare)[1]:.2f} CPU s)")


def store_size(directory: Path) -> tuple[int, int]:
    """(files, bytes) of a store directory (hidden files included)."""
    paths = [p for p in directory.rglob("*") if p.is_file()]
    return len(paths), sum(p.stat().st_size for p in paths)


def fig7(workers: int) -> None:
    plan = plan_sweep("search_fig7")
    random.seed(7)
    sample = random.sample(plan.tasks, 300)
    specs = {}
    for task in sample:
        key = (task["algorithm"], task["robots.count"])
        if key not in specs:
            specs[key] = load_scenario("search/fig7", overrides={"algorithm": key[0], "robots.count": key[1]})
    simulate(specs[key], seed=0)
    start = time.process_time()
    for task in sample:
        simulate(specs[(task["algorithm"], task["robots.count"])], seed=task["seed"]).summary()
    per_run = (time.process_time() - start) / len(sample)
    with tempfile.TemporaryDirectory() as out:
        start, cpu = time.perf_counter(), cpu_seconds()
        frame = run_sweep("search_fig7", executor="process", workers=workers, progress=False, out=out)
        wall, cpu = time.perf_counter() - start, cpu_seconds() - cpu
        files, size = store_size(Path(out))
    n = len(plan.tasks)
    print(f"Fig. 7 full sweep: {n} runs, process executor, {workers} workers: {wall:.1f} s wall ({n / wall:.0f} runs/s), "
          f"{cpu:.1f} CPU s ({cpu / n * 1e3:.2f} ms per run, {cpu / workers:.1f} s on {workers} idle cores), "
          f"{int(frame['error'].notna().sum())} failed; store {files} files, {size / 2**20:.1f} MiB")
    print(f"simulation alone (bare loop, seeded sample of 300 runs): {per_run * 1e3:.2f} CPU ms per run → "
          f"{per_run * n:.1f} CPU s for {n} runs, {per_run * n / workers:.1f} s on {workers} idle cores")


def register_toy_family() -> None:
    """The test suite's toy family (a trivial scenario), in this process and forked workers."""
    sys.path.insert(0, str(ROOT / "tests" / "experiments"))
    import experiments_toy_family
    from robofleet.scenarios import registry

    registry.FAMILIES["toy"] = experiments_toy_family.FAMILY


def million_worker(runs: int, out: str, workers: int) -> None:
    """The sweep itself (run in a child process so that it can be killed)."""
    register_toy_family()
    start = time.perf_counter()
    plan = plan_sweep({**TOY_SWEEP, "seeds": runs})
    print(f"planned {len(plan.tasks)} runs in {time.perf_counter() - start:.1f} s", flush=True)
    frame = run_sweep({**TOY_SWEEP, "seeds": runs}, executor="process", workers=workers, progress=False, out=out)
    print(f"sweep done: {len(frame)} rows, {int(frame['error'].notna().sum())} failed, {time.perf_counter() - start:.1f} s", flush=True)


def million(runs: int, kill_after: float, workers: int, out: Path) -> None:
    command = [sys.executable, __file__, "--million-worker", str(runs), "--out", str(out), "--workers", str(workers)]
    print(f"{runs:,}-run sweep of a trivial scenario (toy family, 1 robot, 1 step), {workers} workers, store {out}")
    start = time.perf_counter()
    child = subprocess.Popen(command, start_new_session=True)
    try:
        child.wait(timeout=kill_after)
    except subprocess.TimeoutExpired:
        os.killpg(child.pid, signal.SIGKILL)
        child.wait()
    first = time.perf_counter() - start
    stored = len(ResultStore(out).finished_ids())
    files, size = store_size(out)
    print(f"killed (SIGKILL) after {first:.0f} s: {stored:,} runs stored, {files} files, {size / 2**20:.1f} MiB")
    start = time.perf_counter()
    subprocess.run(command, check=True)
    resumed = time.perf_counter() - start
    files, size = store_size(out)
    frame = ResultStore(out).read()
    print(f"resumed to the end in {resumed:.0f} s: {len(frame):,} rows, {frame['run_id'].nunique():,} runs, "
          f"{int(frame['error'].notna().sum())} failed; store {files} files (Parquet: {len(list(out.glob('*.parquet')))}), "
          f"{size / 2**20:.1f} MiB; total {first + resumed:.0f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, default=20000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--runs", type=int, default=20, help="seeds per Fig. 7 grid point for the overhead measurement")
    parser.add_argument("--overhead-only", action="store_true", help="only the overhead against a bare loop (part 2)")
    parser.add_argument("--fig7", action="store_true", help="run the full Fig. 7 sweep (26,000 runs)")
    parser.add_argument("--million", type=int, default=0, help="run a sweep of this many trivial runs, kill it, resume it")
    parser.add_argument("--kill-after", type=float, default=300.0)
    parser.add_argument("--out", type=Path, default=None, help="store of --million (default: a temporary directory)")
    parser.add_argument("--million-worker", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.million_worker:
        million_worker(args.million_worker, str(args.out), args.workers)
        return
    print(machine())
    if args.million:
        with tempfile.TemporaryDirectory() as scratch:
            million(args.million, args.kill_after, args.workers, args.out or Path(scratch) / "store")
    elif args.fig7:
        fig7(args.workers)
    else:
        if not args.overhead_only:
            trivial_tasks(args.tasks, args.workers)
        machinery_overhead(args.runs, args.workers)


if __name__ == "__main__":
    main()
