"""Flocking benchmarks (Gervasi & Prencipe 2001): prints throughput figures, asserts nothing.

* ASYNC events (Look-Compute-Move cycles) per second with 100 and 1,000 followers, for
  each algorithm of Sec. 4-6.4 (the engine plus the Compute step; Δ metrics excluded):
  this tree's compiled engine, its interpreted engine (the same trace, in the same
  process), and, with ``--before SRC``, the sources of an unchanged earlier copy (for
  example a ``git worktree`` of the earlier commit: pass its ``src`` folder). Each round
  times every engine once, interleaved, each in a fresh process on the same inputs
  (``--quick``: this tree's engines in this process, one round); the table shows the
  best of ``--rounds`` rounds and the ratios of those bests.
* 𝒟-distance (Def. 3.1, optimal assignment) time for 100 and 1,000 robots.

Run: ``python benchmarks/flocking.py [--quick] [--before OLD/src] [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from _machine import machine

ALGORITHM_NAMES = ("basic", "stripe", "hula_hoop", "randomized")
THIS_SRC = str(Path(__file__).resolve().parent.parent / "src")

#: Times one ASYNC run; uses only what every version of the engine has (``run`` without
#: ``compiled`` unless asked), so the same code times the earlier sources too.
TIMER = r"""
import sys, time, numpy as np
from robofleet.flocking import patterns
from robofleet.flocking.basic import BasicAlgorithm
from robofleet.flocking.hula_hoop import HulaHoopAlgorithm
from robofleet.flocking.leader import LeaderCourse
from robofleet.flocking.model import LocalFrames
from robofleet.flocking.randomized import RandomizedAlgorithm
from robofleet.flocking.schedulers import SchedulerSpec, run
from robofleet.flocking.stripe import StripeAlgorithm
ALGORITHMS = {"basic": BasicAlgorithm, "stripe": StripeAlgorithm, "hula_hoop": HulaHoopAlgorithm, "randomized": RandomizedAlgorithm}

def timed_run(name, n, events, options):
    rng = np.random.default_rng(0)
    pattern = patterns.random_lb_symmetric(n, rng)
    starts = rng.uniform(0, 512, (n, 2))
    speeds = rng.uniform(0.5, 5.0, n)
    spec = SchedulerSpec(kind="async", cycle_min=0.5, cycle_max=1.5, rigidity=0.5)
    duration = events / n  # about one cycle per follower per time unit
    course = LeaderCourse.build([256.0, 256.0], 0.0, 0.2, np.array([duration + 2.0]), np.array([0.0]))
    frames = LocalFrames.random(n, rng)
    t0 = time.perf_counter()
    res = run(ALGORITHMS[name](), pattern, frames, starts, speeds, course, spec, duration=duration,
              sample_dt=max(1.0, duration / 20), scheduler_rng=np.random.default_rng(1),
              algorithm_rng=np.random.default_rng(2), **options)
    return res.looks / (time.perf_counter() - t0), res.looks

def warm_and_time(name, n, events, engine):
    options = {} if engine == "default" else {"compiled": engine == "compiled"}
    timed_run(name, min(n, 10), 50, options)  # warm-up: compiled code loaded, caches filled
    return timed_run(name, n, events, options)
"""
MAIN = """
rate, looks = warm_and_time(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
print(rate, looks)
"""


def time_engine(src: str | None, engine: str, name: str, n: int, events: int) -> tuple[float, int]:
    """(cycles per second, cycles) of one timed run in a fresh process importing ``src``
    (``None``: in this process, this tree)."""
    if src is None:
        namespace: dict = {}
        exec(TIMER, namespace)
        return namespace["warm_and_time"](name, n, events, engine)
    env = {**os.environ, "PYTHONPATH": src}
    out = subprocess.run([sys.executable, "-c", TIMER + MAIN, name, str(n), str(events), engine], env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    return float(out[0]), int(out[1])


def async_table(names, sizes, events_at, before: str | None, rounds: int, in_process: bool) -> list[dict]:
    """Best cycles/s of every engine per (algorithm, followers), engines interleaved per round
    (this tree's in this process when ``in_process``)."""
    here = None if in_process else THIS_SRC
    engines = {"compiled": (here, "compiled"), "interpreted": (here, "interpreted")}
    if before:
        engines["before"] = (before, "default")
    rows = []
    for name in names:
        for n in sizes:
            best = {e: 0.0 for e in engines}
            for _ in range(rounds):
                for label, (src, engine) in engines.items():
                    rate, looks = time_engine(src, engine, name, n, events_at(n))
                    best[label] = max(best[label], rate)
            rows.append({"algorithm": name, "followers": n, "cycles": looks, **best})
    return rows


def print_async_table(rows: list[dict]) -> None:
    has_before = "before" in rows[0]
    print("ASYNC Look-Compute-Move cycles per second (engine + Compute, one core; best of the rounds)")
    head = f"{'algorithm':<11} {'followers':>9} {'cycles':>7} {'compiled':>9} {'interpreted':>11} {'× interp.':>9}"
    print(head + (f" {'before':>8} {'× before':>9}" if has_before else ""))
    for r in rows:
        line = (f"{r['algorithm']:<11} {r['followers']:>9} {r['cycles']:>7} {r['compiled']:>9.0f} {r['interpreted']:>11.0f}"
                f" {r['compiled'] / r['interpreted']:>9.1f}")
        if has_before:
            line += f" {r['before']:>8.0f} {r['compiled'] / r['before']:>9.1f}"
        print(line)


def d_distance_seconds(n: int, repeats: int = 3) -> float:
    from robofleet.flocking import metrics

    rng = np.random.default_rng(0)
    times = []
    for _ in range(repeats):
        c, g = rng.uniform(0, 512, (n, 2)), rng.uniform(0, 512, (n, 2))
        t0 = time.perf_counter()
        metrics.d_distance(c, g)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true",
                        help="fewer events, one round, basic only at 1,000 followers, this tree timed in this process")
    parser.add_argument("--before", help="src folder of an unchanged copy of the earlier sources (adds the ratios to it)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved timing rounds (best is shown)")
    args = parser.parse_args()
    print(machine())
    events = 1000 if args.quick else 4000
    rounds = 1 if args.quick else args.rounds
    rows = []
    for name in ALGORITHM_NAMES:
        sizes = (100,) if args.quick and name != "basic" else (100, 1000)
        rows += async_table([name], sizes, lambda n: events if n == 100 else max(events // 2, 1000), args.before, rounds,
                            in_process=args.quick)
    print_async_table(rows)
    for n in (100, 1000):
        print(f"D-distance (optimal assignment), {n} robots: {d_distance_seconds(n) * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
