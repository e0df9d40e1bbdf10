"""Flocking benchmarks (Gervasi & Prencipe 2001): prints throughput figures, asserts nothing.

* ASYNC events (Look-Compute-Move cycles) per second with 100 and 1,000 followers, for
  each algorithm of Sec. 4-6.4 (the engine plus the Compute step; Δ metrics excluded).
* 𝒟-distance (Def. 3.1, optimal assignment) time for 1,000 robots.

Run: ``python benchmarks/flocking.py [--quick]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from robofleet.flocking import metrics, patterns
from robofleet.flocking.basic import BasicAlgorithm
from robofleet.flocking.hula_hoop import HulaHoopAlgorithm
from robofleet.flocking.leader import LeaderCourse
from robofleet.flocking.model import LocalFrames
from robofleet.flocking.randomized import RandomizedAlgorithm
from robofleet.flocking.schedulers import SchedulerSpec, run
from robofleet.flocking.stripe import StripeAlgorithm

ALGORITHMS = {"basic": BasicAlgorithm(), "stripe": StripeAlgorithm(), "hula_hoop": HulaHoopAlgorithm(), "randomized": RandomizedAlgorithm()}


def async_events_per_second(algorithm, n_followers: int, events: int, seed: int = 0) -> tuple[float, int]:
    """Cycles per wall-clock second of an ASYNC run with ``n_followers`` followers."""
    rng = np.random.default_rng(seed)
    pattern = patterns.random_lb_symmetric(n_followers, rng)
    starts = rng.uniform(0, 512, (n_followers, 2))
    speeds = rng.uniform(0.5, 5.0, n_followers)
    spec = SchedulerSpec(kind="async", cycle_min=0.5, cycle_max=1.5, rigidity=0.5)
    duration = events / n_followers  # about one cycle per follower per time unit
    course = LeaderCourse.build([256.0, 256.0], 0.0, 0.2, np.array([duration + 2.0]), np.array([0.0]))
    frames = LocalFrames.random(n_followers, rng)
    t0 = time.perf_counter()
    res = run(algorithm, pattern, frames, starts, speeds, course, spec, duration=duration, sample_dt=max(1.0, duration / 20),
              scheduler_rng=np.random.default_rng(1), algorithm_rng=np.random.default_rng(2))
    seconds = time.perf_counter() - t0
    return res.looks / seconds, res.looks


def d_distance_seconds(n: int, repeats: int = 3) -> float:
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
    parser.add_argument("--quick", action="store_true", help="fewer events")
    args = parser.parse_args()
    events = 1000 if args.quick else 4000
    print("ASYNC Look-Compute-Move cycles per second (engine + Compute, one core)")
    print(f"{'algorithm':<12} {'followers':>9} {'cycles':>8} {'cycles/s':>10}")
    for name, alg in ALGORITHMS.items():
        for n in (100, 1000):
            if n == 1000 and name != "basic" and args.quick:
                continue
            rate, looks = async_events_per_second(alg, n, events if n == 100 else max(events // 2, 1000))
            print(f"{name:<12} {n:>9} {looks:>8} {rate:>10.0f}")
    for n in (100, 1000):
        print(f"D-distance (optimal assignment), {n} robots: {d_distance_seconds(n) * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
