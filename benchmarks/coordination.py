"""Speed figures of the coordination family (the label-flipping deadlock paper (2021)). Prints figures; asserts nothing.

1. Coordination-space construction (swept-bounding-box pruning) for 20/50/100 robots with
   long trajectories, against the naive dense grid of every pair (sampled pairs, scaled).
2. Time per flip test: incremental cycle test (Pearce–Kelly) vs the full rebuild of the
   active subgraph (edge arrays + strongly connected components), and vs rebuilding the
   segment graph from scratch as the authors' release did; at 100 robots. Target ≥ 20×.
3. Whole-experiment wall time: one Fig. 6 instance (six variants through ``simulate``) per robot
   count, serial, with the per-process plan cache and with planning repeated for every run.

Run:  .venv/bin/python benchmarks/coordination.py [--quick]
"""

from __future__ import annotations

import argparse
import time

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

RADIUS, STEP = 15.0, 5.0


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


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="smaller sizes")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    bench_space((20, 50) if args.quick else (20, 50, 100), rng)
    bench_flip_tests(40 if args.quick else 100, rng, 3000 if args.quick else 20000)
    bench_experiment((5, 10) if args.quick else (5, 10, 15, 20))


if __name__ == "__main__":
    main()
