"""Same seeds, same traces? Compares flocking runs of this tree with an unchanged copy of
an earlier one: prints figures, asserts nothing.

For every shipped ``flocking/*`` scenario (or ``--scenarios``) and seed, runs
:func:`robofleet.simulate` here and, in a subprocess, with the sources of ``--before``
(e.g. a ``git worktree`` of the earlier commit: pass its ``src`` folder), then prints per
run the largest absolute difference of the sampled positions, the share of coordinates
that are bit-identical, and the per-run results (success, convergence times, slot
changes, cycle counts, conditions, final Δ …) that differ in any bit. (The compiled and
interpreted engines of one tree are compared bit for bit by the flocking tests.)

Run: ``python benchmarks/flocking_traces.py --before OLD/src [--seeds 3] [--duration 300]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from _machine import machine

RUNNER = r"""
import json, sys, numpy as np, robofleet
name, seed, duration, out = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
spec = robofleet.load_scenario(name, {"duration": duration})
trace = robofleet.simulate(spec, seed=seed)
np.savez(out, positions=trace.positions)
json.dump({"results": {k: v for k, v in trace.results.items() if isinstance(v, (int, float, str, bool)) or v is None}},
          open(out + ".json", "w"))
"""


def flocking_scenarios() -> list[str]:
    from robofleet.scenarios import catalogue

    return [e.name for e in catalogue.list() if e.family == "flocking"]


def run_in(src: str | None, name: str, seed: int, duration: float, workdir: Path) -> tuple[np.ndarray, dict]:
    """Positions and scalar results of one run with the package found under ``src`` (``None``: this tree)."""
    out = str(workdir / f"{name.replace('/', '_')}_{seed}_{'before' if src else 'after'}.npz")
    env = dict(os.environ)
    if src:
        env["PYTHONPATH"] = src
    subprocess.run([sys.executable, "-c", RUNNER, name, str(seed), str(duration), out], check=True, env=env)
    with np.load(out) as data:
        positions = data["positions"]
    return positions, json.load(open(out + ".json"))["results"]


def differing_results(a: dict, b: dict) -> list[str]:
    """The per-run results that differ (floats compared exactly; NaN equals NaN), each with
    its relative difference when both are numbers."""
    def same(x, y):
        return x == y or (isinstance(x, float) and isinstance(y, float) and np.isnan(x) and np.isnan(y))

    def label(k):
        x, y = a.get(k), b.get(k)
        if isinstance(x, (int, float)) and isinstance(y, (int, float)) and not isinstance(x, bool):
            return f"{k} ({abs(x - y) / max(abs(x), abs(y), 1e-300):.1g} rel.)"
        return f"{k} ({x} vs {y})"
    return [label(k) for k in sorted(set(a) | set(b)) if not same(a.get(k), b.get(k))]


def compare(before_src: str, names: list[str], seeds: int, duration: float) -> None:
    print(f"{'scenario':<34} {'seed':>4} {'max |Δpos|':>11} {'bit-identical':>13}  results that differ")
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            for seed in range(seeds):
                old, old_res = run_in(before_src, name, seed, duration, Path(tmp))
                new, new_res = run_in(None, name, seed, duration, Path(tmp))
                diff = float(np.abs(old - new).max()) if old.shape == new.shape else float("inf")
                same = float(np.mean(old == new)) if old.shape == new.shape else 0.0
                print(f"{name:<34} {seed:>4} {diff:>11.3g} {same:>12.1%}  {', '.join(differing_results(old_res, new_res)) or '-'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--before", help="src folder of an unchanged copy of the earlier sources")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--duration", type=float, default=300.0, help="simulated time units per run")
    parser.add_argument("--scenarios", nargs="*", help="scenario names (default: every flocking scenario)")
    args = parser.parse_args()
    print(machine())
    if not args.before:
        print("nothing to compare: pass --before OLD/src")
        return
    compare(args.before, args.scenarios or flocking_scenarios(), args.seeds, args.duration)


if __name__ == "__main__":
    main()
