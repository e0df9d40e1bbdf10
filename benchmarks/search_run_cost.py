"""CPU cost of one search run over the Fig. 7 grid: ``simulate(spec, seed).summary()``.

A seeded sample of ``--sample`` runs of the shipped ``search_fig7`` sweep (algorithm,
robot count and the sweep's seed of each run; ``random.seed(--draw)``) is simulated in a
bare loop with the grid points' specs validated beforehand, after one warm-up run per
grid point (imports, compilation, the per-grid caches). The figure is the process CPU
time per run (on a shared machine, the work done whatever the load), the best of
``--repeat`` passes; the mean steps per run are shown beside it.

``--breakdown`` times each part of ``simulate`` instead (this tree only).

With ``--baseline SRC`` the same sample also runs against the package under ``SRC`` (an
unchanged checkout's ``src``), each tree in its own subprocess, alternating tree by tree
``--rounds`` times, and the ratio baseline / current of the best figures is printed.

    python benchmarks/search_run_cost.py [--sample 300] [--repeat 3] [--rounds 2] [--baseline /path/to/src]
    python benchmarks/search_run_cost.py --breakdown
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def sampled_runs(sample: int, draw: int) -> list[tuple[object, int]]:
    """``sample`` runs of the Fig. 7 sweep drawn with seed ``draw``: (validated scenario,
    seed) pairs, each scenario simulated once first so that its kernels are loaded."""
    import random

    from robofleet import load_scenario, simulate
    from robofleet.experiments import plan_sweep

    random.seed(draw)
    tasks = random.sample(plan_sweep("search_fig7").tasks, sample)
    specs = {}
    for task in tasks:
        key = (task["algorithm"], task["robots.count"])
        if key not in specs:
            specs[key] = load_scenario("search/fig7", overrides={"algorithm": key[0], "robots.count": key[1]})
            simulate(specs[key], seed=0).summary()
    return [(specs[(t["algorithm"], t["robots.count"])], t["seed"]) for t in tasks]


def measure(sample: int, draw: int, repeat: int) -> dict:
    """Best CPU ms per run of ``repeat`` passes over the sample, in this process."""
    from robofleet import simulate

    runs = sampled_runs(sample, draw)
    passes, steps = [], 0
    for _ in range(repeat):
        start = time.process_time()
        steps = sum(simulate(spec, seed=seed).summary()["n_steps"] for spec, seed in runs)
        passes.append((time.process_time() - start) / len(runs) * 1e3)
    return {"ms_per_run": min(passes), "passes": passes, "steps_per_run": steps / len(runs)}


def breakdown(sample: int, draw: int) -> dict[str, float]:
    """CPU µs per run of each part of ``simulate`` (this tree's functions, called as
    ``simulate`` calls them), over the same sample; the best of two passes per part."""
    from robofleet.search import simulation as sim

    runs = sampled_runs(sample, draw)
    best: dict[str, float] = {}
    for _ in range(2):
        spent: dict[str, float] = {}

        def part(name: str, since: float) -> float:
            now = time.process_time()
            spent[name] = spent.get(name, 0.0) + now - since
            return now

        for spec, seed in runs:
            t = time.process_time()
            problem = sim.build_problem(spec, seed)
            t = part("problem: start vertices, failures", t)
            rec = sim.recorder_for(spec, problem, False)
            t = part("recorder set-up", t)
            batch = sim.SearchBatch([problem], spec.algorithm, [seed], recorder=rec)
            t = part("batch set-up: robot streams, maps, tables", t)
            batch.block, batch.drawn_from, batch.drawn_until = batch.draws(), 0, batch.streams.chunk
            t = part("random draws (a block of 256 steps per robot)", t)
            batch.run_block(0)
            if batch.executed:
                rec.run(batch.step)
            t = part("the steps (compiled loop) and their recording", t)
            outcome = batch.outcome(0)
            t = part("results (shares, counts)", t)
            metadata = sim.run_metadata(spec, problem, outcome)
            t = part("metadata", t)
            trace = rec.trace("search", scenario=spec.scenario_name, seed=seed, metadata=metadata, results=outcome.results,
                              workspace=problem.grid.workspace)
            t = part("trace assembly (events table)", t)
            trace.summary()
            part("summary", t)
        for name, seconds in spent.items():
            best[name] = min(best.get(name, float("inf")), seconds / len(runs) * 1e6)
    return best


def measure_in(src: Path, args: argparse.Namespace) -> dict:
    """:func:`measure` in a subprocess importing robofleet from ``src``."""
    env = {**os.environ, "PYTHONPATH": str(src), "MPLBACKEND": "Agg"}
    command = [sys.executable, __file__, "--worker", "--sample", str(args.sample), "--draw", str(args.draw), "--repeat", str(args.repeat)]
    out = subprocess.run(command, env=env, check=True, capture_output=True, text=True, cwd=src.parent)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=300)
    parser.add_argument("--draw", type=int, default=7, help="seed of the sample's draw")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--baseline", type=Path, default=None, help="src directory of the tree to compare with")
    parser.add_argument("--breakdown", action="store_true", help="CPU µs per run of each part of simulate (this tree)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(measure(args.sample, args.draw, args.repeat)))
        return
    if args.breakdown:
        parts = breakdown(args.sample, args.draw)
        print(f"part of simulate (Fig. 7 sample of {args.sample} runs) | CPU µs per run")
        for name, micros in parts.items():
            print(f"{name} | {micros:.0f}")
        print(f"total | {sum(parts.values()):.0f}")
        return
    sys.path.insert(0, str(Path(__file__).parent))
    from _machine import machine

    print(machine())
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    trees = [("current", ROOT / "src")] + ([("baseline", args.baseline.resolve())] if args.baseline else [])
    best: dict[str, float] = {}
    for round_ in range(args.rounds):
        for name, src in trees:
            result = measure_in(src, args)
            best[name] = min(best.get(name, float("inf")), result["ms_per_run"])
            print(f"round {round_ + 1}, {name}: {result['ms_per_run']:.3f} CPU ms per run (passes "
                  f"{', '.join(f'{p:.3f}' for p in result['passes'])}; {result['steps_per_run']:.1f} steps per run)", flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"Fig. 7 sample of {args.sample} runs, best CPU ms per run: " + ", ".join(f"{k} {v:.3f}" for k, v in best.items()))
    if "baseline" in best:
        print(f"baseline / current: {best['baseline'] / best['current']:.2f}x")


if __name__ == "__main__":
    main()
