"""Speed figures of the coordination family (the label-flipping deadlock paper (2021)). Prints figures; asserts nothing.

1. Coordination-space construction (swept-bounding-box pruning) for 20/50/100 robots with
   long trajectories, against the naive dense grid of every pair (sampled pairs, scaled).
2. Time per flip test: incremental cycle test (Pearce–Kelly) vs the full rebuild of the
   active subgraph (edge arrays + strongly connected components), and vs rebuilding the
   segment graph from scratch as the authors' release did; at 100 robots. Target ≥ 20×.
3. One Fig. 6 instance (six variants through ``simulate``) per robot count, serial, with
   the per-process plan cache and with planning repeated for every run.
4. The whole experiment: the 240 runs of ``robofleet reproduce rmtrack --budget full``
   (sweep ``rmtrack_fig6``, 10 seeds), each round in fresh processes with this tree's
   sources and, with ``--before SRC``, the sources of an unchanged earlier copy (e.g. a
   ``git worktree`` of the earlier commit: pass its ``src`` folder), interleaved. Prints
   wall and CPU seconds per round, the ratio of each round, and whether the two result
   tables are identical value for value (all columns but the measured times).

Run:  .venv/bin/python benchmarks/coordination.py [--quick] [--before OLD/src] [--rounds 3] [--serial] [--only-experiment]
Target: the 240 runs in ≤ 15 s wall on 2 cores (``--executor process --workers 2``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from robofleet import load_scenario, simulate
from robofleet.coordination.coordination_space import build_coordination_space, obstacle_grid
from robofleet.coordination.instance import planned_instance
from robofleet.coordination.label_flipping import KnownProbabilities
from robofleet.coordination.plan_execution import ALL_VARIANTS, Method, PlanExecutor, Variant
from robofleet.coordination.segment_graph import IncrementalCycleDetector, build_segment_layout, has_cycle_full
from robofleet.coordination.trajectories import make_trajectories
from robofleet.core.rng import spawn_seeds

from _machine import machine

RADIUS, STEP = 15.0, 5.0
THIS_SRC = str(Path(__file__).resolve().parent.parent / "src")
TIMING_COLUMNS = ("wall_seconds", "decision_seconds", "plan_seconds")
"""Result columns that are measured times (the only ones allowed to differ between trees)."""

#: One whole-experiment run in a fresh process: the rmtrack reproduction's sweep at a
#: budget, into a fresh store; prints wall and CPU seconds (this process and its workers).
EXPERIMENT_RUN = """
import json, resource, sys, time
t0 = time.perf_counter()
from robofleet.experiments.reproductions import REPRODUCTIONS
from robofleet.experiments.sweep import run_sweep
budget, executor, workers, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
rep = next(r for r in (REPRODUCTIONS.values() if isinstance(REPRODUCTIONS, dict) else REPRODUCTIONS) if r.name == "rmtrack")
frame = run_sweep(rep.sweep_mapping("rmtrack_fig6", rep.budgets[budget]), executor=executor, workers=workers, progress=False, out=out)
wall = time.perf_counter() - t0
cpu = sum(getattr(resource.getrusage(who), f) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN) for f in ("ru_utime", "ru_stime"))
print(json.dumps({"wall": wall, "cpu": cpu, "runs": len(frame)}))
"""


def synthetic_plan(n: int, rng: np.random.Generator, waypoints: int = 5, collision_free: bool = True):
    """Long trajectories at constant density (the square grows with ``n``).

    ``collision_free=False``: polylines through random waypoints (~1000+ steps), for the
    construction benchmark. ``collision_free=True``: straight lines from the left edge to the
    right edge (starts and goals spaced apart, so the plan is non-conflicting by
    construction), each robot delayed by the smallest delay that avoids all earlier robots —
    computed exactly from the close point pairs (k-d trees), not by trial.
    """
    side = 2500.0 * np.sqrt(n / 20)
    if not collision_free:
        paths = []
        for _ in range(n):
            pts = rng.uniform(0, side, (waypoints, 2))
            seg = [np.linspace(a, b, max(2, int(np.linalg.norm(b - a) / STEP)), endpoint=False) for a, b in zip(pts[:-1], pts[1:])]
            paths.append(np.vstack(seg + [pts[-1:]]))
        return make_trajectories(paths, RADIUS, 0.1)
    side = max(side, n * 4 * RADIUS)
    ys = rng.permutation(np.linspace(0, side, n))
    yg = rng.permutation(np.linspace(0, side, n))
    placed_pts, placed_t, timed = np.empty((0, 2)), np.empty(0, dtype=int), []
    for y0, y1 in zip(ys, yg):
        a, b = np.array([0.0, y0]), np.array([side, y1])
        path = a + (b - a) * np.linspace(0, 1, int(np.linalg.norm(b - a) / STEP) + 1)[:, None]
        delay = 0
        if len(placed_pts):
            pairs = cKDTree(path).sparse_distance_matrix(cKDTree(placed_pts), 2 * RADIUS, output_type="ndarray")
            d = np.unique(placed_t[pairs["j"]] - pairs["i"])
            d = d[d >= 0]
            gaps = np.flatnonzero(d != np.arange(len(d)))
            delay = int(gaps[0]) if len(gaps) else len(d)
        traj = np.vstack([np.repeat(path[:1], delay, axis=0), path])
        timed.append(traj)
        placed_pts = np.vstack([placed_pts, traj])
        placed_t = np.concatenate([placed_t, np.arange(len(traj))])
    return make_trajectories(timed, RADIUS, 0.1)


def bench_space(counts, rng):
    print("## coordination-space construction (long trajectories)")
    print("| robots | steps per robot | obstacles | pruned build [s] | naive dense grid [s, est.] | speed-up |")
    print("|---:|---:|---:|---:|---:|---:|")
    for n in counts:
        traj = synthetic_plan(n, rng, collision_free=False)
        t0 = time.perf_counter()
        space = build_coordination_space(traj, check_plan=False)
        pruned = time.perf_counter() - t0
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
        sample = [pairs[k] for k in rng.choice(len(pairs), min(20, len(pairs)), replace=False)]
        t0 = time.perf_counter()
        for i, j in sample:
            obstacle_grid(traj, i, j)
        naive = (time.perf_counter() - t0) * len(pairs) / len(sample)
        print(f"| {n} | {int(traj.lengths.mean())} | {space.n_obstacles} | {pruned:.2f} | {naive:.1f} | {naive / pruned:.0f}× |")


class TimedDetector(IncrementalCycleDetector):
    """Times every incremental flip test and the full rebuilds at the same state."""

    progress = None
    log: list = []
    space = None

    def try_flip(self, obstacle, new_label, progress=None):
        tentative = self.labels.copy()
        tentative[obstacle] = new_label
        t0 = time.perf_counter()
        full = not has_cycle_full(self.layout, tentative, self.progress)
        t_full = time.perf_counter() - t0
        t0 = time.perf_counter()
        layout = build_segment_layout(self.space)
        rebuilt = not has_cycle_full(layout, tentative, self.progress)
        t_rebuild = time.perf_counter() - t0
        t0 = time.perf_counter()
        got = super().try_flip(obstacle, new_label, progress)
        t_inc = time.perf_counter() - t0
        assert got == full == rebuilt
        type(self).log.append((t_inc, t_full, t_rebuild, got))
        return got


def bench_flip_tests(n, rng, max_steps):
    traj = synthetic_plan(n, rng)
    space = build_coordination_space(traj)
    layout = build_segment_layout(space)
    prob = np.full(traj.positions.shape[:2], 0.3)
    TimedDetector.space, TimedDetector.log = space, []

    def always(ctx):
        TimedDetector.progress = ctx.progress
        return True

    run = PlanExecutor(traj, space, Variant(Method.TFF, True), KnownProbabilities(prob, 0.1), prob, layout=layout,
                       flip_test=always, detector=TimedDetector).run(1, max_steps)
    log = np.array(TimedDetector.log, dtype=float)
    inc, full, rebuild = (np.median(log[:, k]) * 1e3 for k in range(3))
    print(f"\n## flip test at {n} robots ({space.n_obstacles} obstacles, {layout.n_nodes} segment vertices, "
          f"{len(log)} tests, {int((1 - log[:, 3]).sum())} refused, run finished: {run.finished})")
    print("| cycle test | median time per flip test [ms] | speed-up of incremental |")
    print("|---|---:|---:|")
    print(f"| incremental (Pearce–Kelly, affected region only) | {inc:.3f} | 1× |")
    print(f"| full: active-subgraph edges + SCC pass | {full:.3f} | {full / inc:.0f}× |")
    print(f"| full: rebuild the segment graph + SCC pass (release) | {rebuild:.3f} | {rebuild / inc:.0f}× |")


def bench_experiment(counts, root_seed: int = 11):
    """One Fig. 6 instance per robot count: the six variants through ``simulate``, planning
    the instance once (the per-process plan cache) and six times (cache cleared before each run)."""
    print("\n## whole experiment (one Fig. 6 instance = six variants through simulate), serial")
    print("| robots | planning [s] | six runs, plan cached [s] | six runs, planned each time [s] | cache speed-up |")
    print("|---:|---:|---:|---:|---:|")
    seed = spawn_seeds(root_seed, 1)[0]
    totals = [0.0, 0.0]
    simulate(load_scenario("coordination/x_corridor_5_tff"), seed=0)  # warm-up: loads the compiled kernels once
    for n in counts:
        specs = [load_scenario("coordination/x_corridor_20", {"robots.count": n, "robots.instance_seed": None,
                                                              "policy.method": v.method.value, "policy.deadlock_check": v.deadlock_check})
                 for v in ALL_VARIANTS]
        walls = []
        for clear_each in (False, True):
            planned_instance.cache_clear()
            t0 = time.perf_counter()
            for spec in specs:
                if clear_each:
                    planned_instance.cache_clear()
                trace = simulate(spec, seed=seed)
            walls.append(time.perf_counter() - t0)
        totals = [t + w for t, w in zip(totals, walls)]
        print(f"| {n} | {trace.results['plan_seconds']:.2f} | {walls[0]:.2f} | {walls[1]:.2f} | {walls[1] / walls[0]:.1f}× |")
    print(f"\none instance of every count: {totals[0]:.1f} s cached, {totals[1]:.1f} s uncached → "
          f"10 instances ≈ {10 * totals[0] / 60:.1f} CPU-minutes cached ({10 * totals[1] / 60:.1f} uncached)")


def experiment_round(src: str, budget: str, executor: str, workers: int, out: Path) -> dict:
    """One whole-experiment run with the sources ``src`` in a fresh process (imports included)."""
    env = {**os.environ, "PYTHONPATH": src}
    done = subprocess.run([sys.executable, "-c", EXPERIMENT_RUN, budget, executor, str(workers), str(out)], env=env,
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def same_rows(a: Path, b: Path) -> tuple[bool, str]:
    """Whether two result stores hold the same rows, value for value, except the measured times."""
    import pandas as pd

    x, y = (pd.read_parquet(p).sort_values("run_id").reset_index(drop=True) for p in (a, b))
    columns = [c for c in x.columns if c not in TIMING_COLUMNS]
    same = list(x.columns) == list(y.columns) and len(x) == len(y) and all(x[c].equals(y[c]) for c in columns)
    return same, f"{len(x)} rows × {len(columns)} columns"


def bench_whole_experiment(before: str | None, rounds: int, budget: str, executors: list[tuple[str, int]]):
    """The rmtrack sweep at ``budget`` per executor: this tree and (``before``) an earlier copy, interleaved."""
    trees = [("before", before)] if before else []
    trees.append(("after", THIS_SRC))
    print(f"\n## whole experiment: the rmtrack_fig6 sweep, budget {budget!r} (fresh processes, imports included), {rounds} rounds")
    for executor, workers in executors:
        label = f"{executor}" + (f", {workers} workers" if executor == "process" else "")
        print(f"\n### {label}")
        print("| round | " + " | ".join(f"{name} wall [s] | {name} CPU [s]" for name, _ in trees) + (" | wall ratio |" if before else ""))
        print("|---:|" + "---:|---:|" * len(trees) + ("---:|" if before else ""))
        walls = {name: [] for name, _ in trees}
        with tempfile.TemporaryDirectory() as tmp:
            for r in range(rounds):
                stores, cells = {}, []
                for name, src in trees:
                    stores[name] = Path(tmp) / f"{name}_{r}"
                    got = experiment_round(src, budget, executor, workers, stores[name])
                    walls[name].append(got["wall"])
                    cells.append(f"{got['wall']:.1f} | {got['cpu']:.1f}")
                ratio = f" {walls['before'][-1] / walls['after'][-1]:.1f}× |" if before else ""
                print(f"| {r + 1} | " + " | ".join(cells) + " |" + ratio)
            summary = "; ".join(f"{name}: best {min(w):.1f} s, median {statistics.median(w):.1f} s" for name, w in walls.items())
            print(f"\n{summary}")
            if before:
                ratios = [b / a for b, a in zip(walls["before"], walls["after"])]
                same, size = same_rows(stores["before"], stores["after"])
                print(f"ratio before/after: best-of-rounds {min(walls['before']) / min(walls['after']):.1f}×, "
                      f"median of per-round ratios {statistics.median(ratios):.1f}×; "
                      f"rows identical except measured times: {'yes' if same else 'NO'} ({size})")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="smaller sizes (and the smallest experiment budget)")
    parser.add_argument("--before", help="src folder of an unchanged earlier copy, timed against this tree")
    parser.add_argument("--rounds", type=int, default=3, help="whole-experiment rounds (default 3)")
    parser.add_argument("--only-experiment", action="store_true", help="only the whole-experiment figures")
    parser.add_argument("--serial", action="store_true", help="also time the whole experiment on one process")
    args = parser.parse_args()
    print(machine())
    budget = "smallest" if args.quick else "full"
    executors = [("process", 2)] + ([("serial", 1)] if args.serial else [])
    bench_whole_experiment(args.before, args.rounds, budget, executors)
    if args.only_experiment:
        return
    rng = np.random.default_rng(0)
    bench_space((20, 50) if args.quick else (20, 50, 100), rng)
    bench_flip_tests(40 if args.quick else 100, rng, 3000 if args.quick else 20000)
    bench_experiment((5, 10) if args.quick else (5, 10, 15, 20))


if __name__ == "__main__":
    main()
