"""Liveness of B-UAVC: success, arrivals, travel time and contacts over many seeds.

For each shipped 2-D avoidance scenario (``scenarios/avoidance/*.yaml`` without
``space3d``) runs ``--seeds`` seeds with the shipped step budget, and ``--random``
scenarios of :func:`robofleet.avoidance.random_scenarios.random_scenario` (8–16 robots,
random antipodal swap, random convex obstacles; one seed each). Prints, per scenario,
success with its Clopper–Pearson 95 % interval, the share of robots that arrived, the
mean travel time over successful runs, contacts and the per-step contact rate's 95 %
upper bound (next to δ), and the shares of robot-steps whose estimate lay in its own
cell and whose cell was empty (the premise of the guarantee). ``--liveness on|off|spec``
switches the navigation stages (``navigation.enabled``; ``spec`` keeps the scenario's).

``--before-after`` prints, per scenario, the paper's controller at the budget the
scenarios shipped with before the liveness rules (:data:`EARLIER_BUDGETS`; what a user
got) next to the shipped scenario (liveness rules on, budget by the straight-line rule),
and the mean travel time of the runs both finish, paired by seed.

Run: ``python benchmarks/avoidance_liveness.py [--seeds 20] [--random 20] [--first-seed 0] [--random-first-seeds 1000 3000] [--scenarios ten_boxes ...] [--liveness off] [--budget-factor 4] [--before-after] [--generator polygons|boxes|room] [--jobs 2]``
(``--scenarios`` with no name runs only the random scenarios; ``--generator boxes|room``
draws them from another generator of :mod:`robofleet.avoidance.random_scenarios` (a seed
whose layout cannot be placed is left out and named, and so are the seeds that end with a
robot away from home); every run is seeded, so any seed
range can be re-run and ``--jobs`` does not change a figure).
"""

from __future__ import annotations

import argparse
import glob
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import yaml
from scipy.stats import beta

import robofleet
from robofleet.avoidance.random_scenarios import GENERATORS, random_scenario, scene
from robofleet.core.errors import ScenarioError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


EARLIER_BUDGETS = {"antipodal_swap": 500, "circle_swap": 500, "diff_drive": 800, "double_integrator": 600,
                   "ten_boxes": 500, "three_boxes": 500, "random": 588}
"""``max_steps`` of the scenarios before the straight-line rule (random: 2.5 × straight line)."""


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval of ``k`` successes in ``n`` trials (Clopper & Pearson 1934)."""
    a = (1 - level) / 2
    lo = beta.ppf(a, k, n - k + 1) if k > 0 else 0.0
    hi = beta.ppf(1 - a, k + 1, n - k) if k < n else 1.0
    return float(lo), float(hi)


def shipped_mappings(names: list[str] | None) -> dict[str, dict]:
    """The shipped 2-D scenarios as mappings, by name."""
    out = {}
    for path in sorted(glob.glob(os.path.join(ROOT, "scenarios", "avoidance", "*.yaml"))):
        with open(path) as fh:
            data = yaml.safe_load(fh)
        name = os.path.splitext(os.path.basename(path))[0]
        if data.get("space3d") is None and (not names or name in names):
            out[name] = data
    return out


def with_liveness(mapping: dict, mode: str, budget_factor: float = 1.0) -> dict:
    """``mapping`` with its navigation stages switched on/off (``spec`` keeps them) and its
    step budget multiplied by ``budget_factor``."""
    out = {**mapping, "max_steps": int(round(budget_factor * mapping.get("max_steps", 500)))}
    if mode != "spec":
        out["navigation"] = {**mapping.get("navigation", {}), "enabled": mode == "on"}
    return out


def run(mapping: dict, seed: int) -> dict:
    """The summary of one run (cells not recorded)."""
    spec = robofleet.load_scenario({**mapping, "record_cells": False})
    trace = robofleet.simulate(spec, seed=seed)
    positions = trace.arrays["positions"]
    return {**trace.results, "seed": seed, "robot_steps": int(positions.shape[0] * positions.shape[1])}


def _run_pair(job: tuple[dict, int]) -> dict:
    return run(*job)


def _run_random_pair(job: tuple[dict, int]) -> dict | None:
    """:func:`run` of a random scene; ``None`` when its layout cannot be placed (the start
    sampler finds no free start for some robot)."""
    try:
        return run(*job)
    except ScenarioError:
        return None


JOBS = 1
"""Worker processes for the runs (``--jobs``); each run is seeded, so results do not depend on it."""


def run_all(mappings: list[dict], seeds: list[int], one=_run_pair) -> list[dict]:
    """``one`` (:func:`run`) of every ``(mapping, seed)`` pair, in order, on :data:`JOBS` processes."""
    jobs = list(zip(mappings, seeds))
    if JOBS <= 1:
        return [one(job) for job in jobs]
    with ProcessPoolExecutor(JOBS) as pool:
        return list(pool.map(one, jobs))


def paired_travel_time(before: list[dict], after: list[dict]) -> str:
    """Mean travel time before → after over the seeds both finish, and the change."""
    both = [(b["mean_travel_time"], a["mean_travel_time"]) for b, a in zip(before, after) if b["success"] and a["success"]]
    if not both:
        return "— (no seed finished by both)"
    tb, ta = np.mean(both, axis=0)
    return f"{tb:.1f} → {ta:.1f} s ({100 * (ta / tb - 1):+.0f} %, {len(both)} seeds)"


def summarise(label: str, results: list[dict], delta: float) -> str:
    """One table row of a batch of runs."""
    n = len(results)
    k = sum(bool(r["success"]) for r in results)
    lo, hi = clopper_pearson(k, n)
    arrived = np.mean([r["arrived"] for r in results])
    times = [r["mean_travel_time"] for r in results if r["success"]]
    contacts = sum(int(r["collision_steps"]) for r in results)
    steps = sum(r["robot_steps"] for r in results)
    rate_hi = clopper_pearson(contacts, max(steps, 1))[1] if steps else float("nan")
    t = f"{np.mean(times):.1f}" if times else "—"
    inside = np.mean([r["estimate_in_cell_share"] for r in results])
    empty = np.mean([r["empty_cell_share"] for r in results])
    livelocks = sum(int(r.get("livelock_detections", 0)) for r in results)
    deadlocks = sum(int(r["deadlock_detections"]) for r in results)
    return (f"| {label} | {n} | {100 * k / n:.0f} % [{100 * lo:.0f}, {100 * hi:.0f}] | {100 * arrived:.0f} % | {t} | "
            f"{contacts} | {rate_hi:.1e} (δ = {delta}) | {100 * inside:.0f} % | {100 * empty:.1f} % | {deadlocks - livelocks} / {livelocks} |")


HEADER = ("| scenario | runs | success [CP 95 %] | arrived | mean travel time of successes [s] | contact steps | "
          "robot-step contact rate, 95 % upper | estimate in cell | empty cell | stuck: deadlock / livelock |\n"
          "|---|---:|---:|---:|---:|---:|---|---:|---:|---:|")


def before_after(name: str, mapping: dict, seeds: range, delta: float) -> list[str]:
    """Two table rows (the paper's controller at the earlier budget, the shipped scenario)
    and the paired travel time."""
    before = {**mapping, "max_steps": EARLIER_BUDGETS[name], "navigation": {"enabled": False}}
    rows_b = run_all([before] * len(seeds), list(seeds))
    rows_a = run_all([mapping] * len(seeds), list(seeds))
    return [summarise(f"{name}, before", rows_b, delta), summarise(f"{name}, shipped", rows_a, delta),
            f"|  | travel time, seeds both finish: {paired_travel_time(rows_b, rows_a)} |  |  |  |  |  |  |  |  |"]


def random_rows(rnd: range, liveness: str, budget_factor: float, generator: str = "polygons") -> list[dict]:
    """Runs of the random scenes of ``generator`` for the seeds of ``rnd`` (scenario seed =
    run seed); seeds whose layout cannot be placed are named and left out."""
    rows = run_all([with_liveness(scene(generator, s), liveness, budget_factor) for s in rnd], list(rnd), _run_random_pair)
    unplaced = [s for s, row in zip(rnd, rows) if row is None]
    if unplaced:
        print(f"{generator}: no layout for seeds {unplaced} (left out)", flush=True)
    not_home = [s for s, row in zip(rnd, rows) if row is not None and not row["success"]]
    if not_home:
        print(f"{generator}: not every robot home at the end of seeds {not_home}", flush=True)
    return [row for row in rows if row is not None]


def random_before_after(rnd: range) -> list[str]:
    """The before/after rows of the random scenarios of ``rnd``."""
    rows_b = run_all([{**random_scenario(s), "max_steps": EARLIER_BUDGETS["random"], "navigation": {"enabled": False}} for s in rnd], list(rnd))
    rows_a = random_rows(rnd, "spec", 1.0)
    return [summarise(f"random {rnd.start}–{rnd.stop - 1}, before", rows_b, 0.1),
            summarise(f"random {rnd.start}–{rnd.stop - 1}, shipped", rows_a, 0.1),
            f"|  | travel time, seeds both finish: {paired_travel_time(rows_b, rows_a)} |  |  |  |  |  |  |  |  |"]


def main() -> None:
    global JOBS
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="seeds per shipped scenario")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--random", type=int, default=20, help="random scenarios per seed range")
    ap.add_argument("--random-first-seeds", type=int, nargs="*", default=None,
                    help="first seed of each range of random scenarios (default: --first-seed)")
    ap.add_argument("--scenarios", nargs="*", default=None, help="shipped scenario names (default: all 2-D; none: only random)")
    ap.add_argument("--liveness", choices=["on", "off", "spec"], default="spec")
    ap.add_argument("--budget-factor", type=float, default=1.0, help="multiply every step budget (1 = as shipped)")
    ap.add_argument("--before-after", action="store_true", help="the paper's controller at the earlier budgets next to the shipped scenarios")
    ap.add_argument("--generator", choices=sorted(GENERATORS), default="polygons", help="the random scenes' generator")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (results do not depend on it)")
    args = ap.parse_args()
    if args.before_after and args.generator != "polygons":
        ap.error("--before-after: expected the polygons generator (the earlier budgets are theirs), received --generator " + args.generator)
    JOBS = args.jobs
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print(HEADER)
    t0 = time.perf_counter()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    shipped = shipped_mappings(args.scenarios) if args.scenarios != [] else {}
    ranges = [range(f, f + args.random) for f in (args.random_first_seeds or [args.first_seed])] if args.random else []
    for name, mapping in shipped.items():
        if args.before_after:
            print("\n".join(before_after(name, mapping, seeds, mapping.get("delta", 0.1))), flush=True)
        else:
            m = with_liveness(mapping, args.liveness, args.budget_factor)
            print(summarise(name, run_all([m] * len(seeds), list(seeds)), mapping.get("delta", 0.1)), flush=True)
    for rnd in ranges:
        if args.before_after:
            print("\n".join(random_before_after(rnd)), flush=True)
        else:
            rows = random_rows(rnd, args.liveness, args.budget_factor, args.generator)
            print(summarise(f"{args.generator} (seeds {rnd.start}–{rnd.stop - 1})", rows, 0.1), flush=True)
    print(f"wall time: {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
