"""Grid search at scale: step cost of the search (Yang 2017) for 1–1,000 robots on grids of
~10⁴–10⁶ vertices, before/after in one run.

The area is the Fig. 7 area (``scenarios/search/fig7.yaml``) scaled by ``f`` — rectangle,
corner radius, the four obstacles and the nine targets — with the grid edge kept at
``a = 1``, so the triangular grid has about ``138.6 f²`` vertices; the robots start at
distinct accessible vertices drawn uniformly from a seeded generator (a team deployed over
the area: 1,000 robots do not fit on the border of the 10⁴-vertex area), in situation 2
(search the whole area, stop rule (4): a team of 1,000 finds the nine targets of
situation 1 within a few steps). Every point
builds the spec (validation builds the grid), the problem (sensing tables), then runs
``--warmup`` steps untimed (compilation, first flights) and times the next ``--steps``
steps of :class:`~robofleet.search.simulation.SearchBatch` (the loop of ``run_search``:
choose, move, sense, exchange, stop check). Figures: milliseconds per step, robot-steps
per second and the growth factors 100 → 1,000 robots (reference: linear, ×10) and
10⁴ → 10⁶ vertices (reference: ×1 for a step cost independent of the grid size).

With ``--baseline SRC`` every point also runs against the package under ``SRC`` (an
unchanged checkout's ``src``) in its own subprocess, alternating with the current tree
round by round, and the ratio before/after is printed (median of ``--rounds`` rounds;
each round takes the best of the steps' block once). Points the baseline cannot run are
reported with the reason.

    python benchmarks/search_scale.py [--vertices 1e4 1e5 1e6] [--robots 1 13 100 1000]
        [--algorithms proposed ru] [--steps 40] [--warmup 10] [--rounds 3] [--baseline /path/to/src]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

FIG7_CELLS = 138.6
"""Vertices of the triangular a = 1 grid per unit of f² on the scaled 12 × 10 Fig. 7 area (≈ 1.155 · 120)."""


def scale_factor(vertices: float) -> float:
    """The scale ``f`` of the Fig. 7 area whose triangular grid has about ``vertices`` vertices."""
    return round((vertices / FIG7_CELLS) ** 0.5, 3)


def scaled_overrides(f: float) -> dict:
    """Spec overrides that scale the Fig. 7 area (bounds, corner radius, obstacles, targets) by ``f``."""
    from robofleet.scenarios.registry import read_scenario

    data, _ = read_scenario("search/fig7")
    ws = data["workspace"]
    return {
        "workspace.rectangle": [c * f for c in ws["rectangle"]],
        "workspace.corner_radius": ws["corner_radius"] * f,
        "workspace.obstacles": [[[x * f, y * f] for x, y in poly] for poly in ws["obstacles"]],
        "targets": [[x * f, y * f] for x, y in data["targets"]],
        "require_guarantee": False,
        "situation": 2,
    }


def scaled_spec(f: float, algorithm: str, n_robots: int, seed: int, situation: int = 2):
    """The scaled Fig. 7 spec with ``n_robots`` at distinct random accessible vertices (seeded)."""
    import numpy as np

    from robofleet import load_scenario

    overrides = {**scaled_overrides(f), "situation": situation}
    base = load_scenario("search/fig7", {**overrides, "robots.count": 1, "algorithm": algorithm})
    grid = base.built_grid()
    free = np.flatnonzero(grid.accessible & grid.reachable_from([int(np.argmax(grid.accessible))]))
    starts = np.random.default_rng(seed).choice(free, size=n_robots, replace=False)
    return load_scenario("search/fig7", {**overrides, "algorithm": algorithm,
                                         "robots": {"starts": grid.points[np.sort(starts)].tolist()}})


def measure_point(f: float, algorithm: str, n_robots: int, steps: int, warmup: int, seed: int) -> dict:
    """Construction seconds and the timed block of ``steps`` loop steps after ``warmup`` steps."""
    from robofleet.search.simulation import SearchBatch, build_problem

    t0 = time.perf_counter()
    spec = scaled_spec(f, algorithm, n_robots, seed)
    t1 = time.perf_counter()
    problem = build_problem(spec, seed)
    t2 = time.perf_counter()
    batch = SearchBatch([problem], algorithm, [seed])
    advance = steps_runner(batch)
    k, done = advance(0, warmup)
    start, first = time.perf_counter(), k
    k, done = advance(k, warmup + steps)
    seconds = time.perf_counter() - start
    return {"vertices": problem.grid.n_vertices, "spec_s": t1 - t0, "problem_s": t2 - t1,
            "steps": k - first, "step_ms": 1e3 * seconds / max(k - first, 1), "done": bool(done)}


def steps_runner(batch):
    """``advance(k, stop) -> (k', done)``: the batch's steps from ``k`` (observing step 0
    first) until ``stop`` or until every run stopped — compiled blocks
    (``SearchBatch.run_block``), or the step-by-step loop of a tree without them."""
    if hasattr(batch, "run_block"):
        def advance(k: int, stop: int) -> tuple[int, bool]:
            while k < stop and not batch.finished:
                batch.run_block(k, stop)
                k = batch.executed
            return k, batch.finished
        return advance

    state = {"done": batch.observe(0)}

    def advance_by_step(k: int, stop: int) -> tuple[int, bool]:
        while k < stop and not state["done"]:
            state["done"] = batch.advance(k)
            k += 1
        return k, state["done"]
    return advance_by_step


def worker(args: argparse.Namespace) -> None:
    """Measure every algorithm and robot count of one grid size in this process (the grid is
    built once); print one JSON line per point."""
    from robofleet.core.errors import RobofleetError

    for alg in args.algorithms:
        for n in args.robots:
            try:
                out = measure_point(args.scale, alg, n, args.steps, args.warmup, args.seed)
            except (RobofleetError, MemoryError) as exc:  # a point the code under test refuses is reported
                out = {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0][:160]}"}
            print(json.dumps({"algorithm": alg, "robots": n, **out}), flush=True)


def run_worker(src: str, scale: float, robots: list[int], args: argparse.Namespace) -> dict[tuple[str, int], dict]:
    """One worker subprocess on the package under ``src``: ``{(algorithm, robots): point}``."""
    cmd = [sys.executable, __file__, "--worker", "--scale", str(scale), "--algorithms", *args.algorithms, "--steps",
           str(args.steps), "--warmup", str(args.warmup), "--seed", str(args.seed), "--robots", *map(str, robots)]
    env = {**os.environ, "PYTHONPATH": src, "ROBOFLEET_MEMORY_BUDGET": args.memory_budget}
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    points = {}
    for line in done.stdout.splitlines():
        row = json.loads(line)
        points[row.pop("algorithm"), row.pop("robots")] = row
    for alg in args.algorithms:
        for n in robots:
            points.setdefault((alg, n), {"error": f"worker exited with {done.returncode}: {done.stderr.strip().splitlines()[-1:]}"})
    return points


def baseline_refusal(n: int, vertices: float) -> str | None:
    """Why the unchanged code cannot run a point (its own memory estimates), or ``None``.

    Its sensing tables hold eight V-bit rows per vertex (the 4 GiB budget refuses the spec
    from ~6·10⁴ vertices on), and its map exchange allocates an ``(n, n, 4, V/64)`` uint64
    array per step."""
    tables = 8 * vertices**2 / 8
    if tables > 4 * 2**30:
        return f"refused: sensing tables need {tables / 2**30:.0f} GiB"
    exchange = n * n * 4 * (-(-int(vertices) // 64)) * 8
    if exchange > 2**31:
        return f"not run: exchange needs {exchange / 2**30:.1f} GiB per step"
    return None


def median_point(rounds: list[dict]) -> dict:
    """The median step time over rounds (the first round's construction figures)."""
    good = [r for r in rounds if "error" not in r]
    if not good:
        return rounds[0]
    return {**good[0], "step_ms": statistics.median(r["step_ms"] for r in good),
            "spec_s": statistics.median(r["spec_s"] for r in good), "problem_s": statistics.median(r["problem_s"] for r in good)}


def cell(point: dict | None) -> str:
    """A step time, ``—`` when not measured, or the first word of why not (``refused``, ``not``)."""
    if point is None:
        return "—"
    return point["error"].split(":")[0][:12] if "error" in point else f"{point['step_ms']:.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 13, 100, 1000])
    parser.add_argument("--algorithms", nargs="+", default=["proposed", "ru"])
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--warmup", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--baseline", default=None, help="src directory of an unchanged checkout to compare with")
    parser.add_argument("--memory-budget", default="4GiB", help="memory budget of the workers (the library default)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--scale", type=float, default=1.0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args)
        return
    sys.path.insert(0, str(Path(__file__).parent))
    from _machine import machine

    print(machine())
    print(f"{args.steps} timed steps after {args.warmup} warm-up steps, median of {args.rounds} rounds, seed {args.seed}")
    here = str(Path(__file__).resolve().parents[1] / "src")
    results = {}
    for v in args.vertices:
        f = scale_factor(v)
        before_robots = [n for n in args.robots if baseline_refusal(n, v) is None]
        rounds_after, rounds_before = [], []
        for _ in range(args.rounds):
            if args.baseline and before_robots:
                rounds_before.append(run_worker(args.baseline, f, before_robots, args))
            rounds_after.append(run_worker(here, f, args.robots, args))
        for alg in args.algorithms:
            for n in args.robots:
                after = median_point([r[alg, n] for r in rounds_after])
                before = None
                if args.baseline:
                    before = (median_point([r[alg, n] for r in rounds_before]) if n in before_robots else
                              {"error": baseline_refusal(n, v)})
                results[alg, v, n] = (before, after)
    for alg in args.algorithms:
        print_table(alg, args, results)


def print_table(alg: str, args: argparse.Namespace, results: dict) -> None:
    """Per grid size and robot count: before / after ms per step, ratio, robot-steps/s, growth."""
    print(f"\n{alg}: ms per step (before | after), ratio, robot-steps/s after, construction s after (spec + problem)")
    print(f"{'vertices':>9} {'robots':>6} {'before ms':>12} {'after ms':>9} {'ratio':>7} {'robot-steps/s':>14} {'build s':>8}")
    for v in args.vertices:
        for n in args.robots:
            before, after = results[alg, v, n]
            ratio = (f"{before['step_ms'] / after['step_ms']:.1f}" if before and "error" not in before and "error" not in after else "—")
            rate = f"{n * 1e3 / after['step_ms']:.0f}" if "error" not in after else "—"
            build = f"{after['spec_s'] + after['problem_s']:.1f}" if "error" not in after else "—"
            nv = after.get("vertices", int(v))
            why = f"  ({before['error']})" if before and "error" in before else ""
            print(f"{nv:>9} {n:>6} {cell(before):>12} {cell(after):>9} {ratio:>7} {rate:>14} {build:>8}{why}")
    lo_n, hi_n = min(args.robots), max(args.robots)
    if 100 in args.robots and 1000 in args.robots:
        lo_n, hi_n = 100, 1000
    for v in args.vertices:
        a, b = results[alg, v, lo_n][1], results[alg, v, hi_n][1]
        if "error" not in a and "error" not in b:
            print(f"growth {lo_n} -> {hi_n} robots at {a['vertices']} vertices: x{b['step_ms'] / a['step_ms']:.2f} "
                  f"(linear reference x{hi_n / lo_n:.0f})")
    lo_v, hi_v = min(args.vertices), max(args.vertices)
    for n in args.robots:
        a, b = results[alg, lo_v, n][1], results[alg, hi_v, n][1]
        if "error" not in a and "error" not in b:
            print(f"growth {a['vertices']} -> {b['vertices']} vertices with {n} robots: x{b['step_ms'] / a['step_ms']:.2f} "
                  f"(reference x1 for a step cost independent of V; x{b['vertices'] / a['vertices']:.0f} for one linear in V)")


if __name__ == "__main__":
    main()
