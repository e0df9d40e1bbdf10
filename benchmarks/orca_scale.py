"""Time of one ORCA step (all agents at once) on a dense crowd.

Agents on a jittered grid of spacing 0.45 m (radius 0.2 m), random current velocities,
each heading for the point mirrored through the origin: most agents' velocity programs
are infeasible, so the least-violation fallback (Sec. 5.2 of van den Berg et al. 2011)
dominates. Prints seconds per step and the share of agents in the fallback (for RVO2's
C++ ORCA on the same crowd see ``vs_rvo2.py``).

Run: ``python benchmarks/orca_scale.py [--sizes 1000 10000] [--threads 1]``
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from _machine import machine

from robofleet.avoidance.orca import OrcaParams, orca_velocities, preferred_velocities


def crowd(n: int, rng: np.random.Generator):
    side = int(np.ceil(np.sqrt(n)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n] * 0.45
    positions = grid + rng.normal(size=grid.shape) * 0.02
    velocities = rng.normal(size=grid.shape) * 0.1
    return positions, velocities, preferred_velocities(positions, -positions, 0.4, 0.1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=numba.get_num_threads())
    args = ap.parse_args()
    numba.set_num_threads(args.threads)
    print(machine())
    params = OrcaParams()
    rng = np.random.default_rng(0)
    warm = crowd(200, rng)
    orca_velocities(*warm[:2], warm[2], 0.2, 0.4, params, 0.1)  # compile the kernels once
    print(f"{'agents':>8} {'ms/step (best of ' + str(args.repeats) + ')':>20} {'in fallback':>12}")
    for n in args.sizes:
        pos, vel, pref = crowd(n, rng)
        best, share = np.inf, 0.0
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            _, infeasible = orca_velocities(pos, vel, pref, 0.2, 0.4, params, 0.1)
            best = min(best, time.perf_counter() - t0)
            share = infeasible.mean()
        print(f"{n:>8} {best * 1e3:>20.2f} {share:>12.1%}")


if __name__ == "__main__":
    main()
