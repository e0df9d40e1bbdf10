"""Same seeds, same traces: the grid search (Yang 2017) of this tree against another checkout.

Runs a fixed list of cases — the four algorithms of Fig. 7 on the Fig. 7 area for 1–30
robots, situation 2 on the three grid kinds, failure injection (listed and random),
trapezoidal rotation, obstacle sensing below Assumption 2.4, lockstep batches, and the
Fig. 7 area scaled to ~10⁴ vertices with 100 robots for 60 steps (situation 2; LFP in
situation 1) — each over several
seeds, in two subprocesses (this tree's ``src`` and ``--baseline SRC``), and compares a
SHA-256 digest of every trace: the ``positions``, ``vertex`` and ``time`` arrays, the
events, the results and the metadata (wall-clock figures excluded). Prints the machine,
the number of traces compared and every case that differs; exit status 1 if any does.

    python benchmarks/search_traces.py --baseline /path/to/unchanged/src [--seeds 5]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

FIG7 = "search/fig7"
RUN_METADATA = ("seed", "n_steps", "algorithm", "situation", "grid", "targets", "starts", "accessible", "visited", "assumptions")
"""The metadata compared: what the run decided (the rest describes the recording, which other changes may extend)."""


def cases(seeds: int) -> list[tuple[str, dict, list[int]]]:
    """``(scenario, overrides, seeds)`` of every compared case."""
    seed_list = list(range(seeds))
    out = []
    for alg in ("proposed", "rule1", "ru", "lfp"):
        for n in (1, 3, 8, 13, 30):
            out.append((FIG7, {"algorithm": alg, "robots.count": n}, seed_list))
        out.append((FIG7, {"algorithm": alg, "robots.count": 6, "timing.rotation_mode": "trapezoidal"}, seed_list))
    for alg in ("proposed", "rule1", "ru"):
        for kind in ("triangular", "square", "hexagonal"):
            out.append(("search/situation2_coverage", {"algorithm": alg, "grid.kind": kind, "robots.count": 5,
                                                       "require_guarantee": False}, seed_list))
    out.append(("search/failure_injection", {}, seed_list))
    for alg in ("proposed", "ru"):
        out.append((FIG7, {"algorithm": alg, "robots.count": 8, "random_failures": {"count": 3, "within_steps": 20}}, seed_list))
        out.append((FIG7, {"algorithm": alg, "robots.count": 5, "ranges.r_so": 0.9, "require_guarantee": False}, seed_list))
    return out


def digest(trace) -> str:
    """SHA-256 of a trace's arrays (wall-clock ``step_seconds`` aside), events, results and
    :data:`RUN_METADATA`."""
    h = hashlib.sha256()
    for name in sorted(trace.arrays):
        if name != "step_seconds":
            h.update(name.encode())
            h.update(trace.arrays[name].tobytes())
    meta = {k: trace.metadata.get(k) for k in RUN_METADATA}
    h.update(json.dumps([trace.events, trace.results, meta], sort_keys=True, default=str).encode())
    return h.hexdigest()


def scaled_digests(seeds: list[int]) -> list[str]:
    """The Fig. 7 area scaled to ~10⁴ vertices, 100 robots, 60 recorded steps per seed."""
    sys.path.insert(0, str(Path(__file__).parent))
    from search_scale import scale_factor, scaled_spec

    from robofleet import simulate

    out = []
    for alg in ("proposed", "ru", "lfp"):
        for seed in seeds:
            spec = scaled_spec(scale_factor(1e4), alg, 100, seed, 1 if alg == "lfp" else 2).model_copy(update={"max_steps": 60})
            out.append(digest(simulate(spec, seed=seed)))
    return out


def batch_digests(seeds: list[int]) -> list[str]:
    """Lockstep batches (``run_search_batch``): the results of every run."""
    from robofleet import load_scenario
    from robofleet.search.simulation import build_problem, run_search_batch

    out = []
    for alg in ("proposed", "ru", "lfp"):
        spec = load_scenario(FIG7, {"algorithm": alg, "robots.count": 7})
        problems = [build_problem(spec, s) for s in seeds]
        results = [o.results for o in run_search_batch(problems, alg, seeds)]
        out.append(hashlib.sha256(json.dumps(results, sort_keys=True).encode()).hexdigest())
    return out


def worker(seeds: int) -> None:
    """Print ``{case: [digest per seed]}`` as one JSON document."""
    from robofleet import load_scenario, simulate

    out = {}
    for scenario, overrides, seed_list in cases(seeds):
        spec = load_scenario(scenario, overrides)
        out[f"{scenario} {json.dumps(overrides, sort_keys=True)}"] = [digest(simulate(spec, seed=s)) for s in seed_list]
    out["scaled 1e4 vertices, 100 robots, 60 steps"] = scaled_digests(list(range(min(seeds, 3))))
    out["lockstep batches of 7 robots"] = batch_digests(list(range(seeds)))
    print(json.dumps(out))


def run(src: str, seeds: int) -> dict:
    env = {**os.environ, "PYTHONPATH": src}
    done = subprocess.run([sys.executable, __file__, "--worker", "--seeds", str(seeds)], env=env, capture_output=True,
                          text=True, check=False)
    if done.returncode:
        raise SystemExit(f"worker on {src} failed: {done.stderr.strip().splitlines()[-1:]}")
    return json.loads(done.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="src directory of the checkout to compare with")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.seeds)
        return
    sys.path.insert(0, str(Path(__file__).parent))
    from _machine import machine

    print(machine())
    if not args.baseline:
        print("nothing to compare: pass --baseline OLD/src (the src folder of an unchanged checkout)")
        return
    here = str(Path(__file__).resolve().parents[1] / "src")
    after, before = run(here, args.seeds), run(args.baseline, args.seeds)
    differing = [case for case in after if after[case] != before.get(case)]
    total = sum(len(v) for v in after.values())
    print(f"{total} traces/digests in {len(after)} cases compared; {len(differing)} cases differ")
    for case in differing:
        print(f"  differs: {case}")
    sys.exit(1 if differing else 0)


if __name__ == "__main__":
    main()
