"""A million single-integrator B-UAVC robots: the step time, and a long run that records
only every k-th step (``record_every``) within the memory it is given.

Scenario: ``avoidance_scale.py``'s circle swap (spacing 4 r_s, so a circle of 127 km for
10⁶ robots; r_s = 0.2 m, v_max = 0.4 m/s, σ = 0.1 m, Δt = 0.1 s), B-UAVC as shipped
(``--navigation on``, the default: the navigation stages on) or the paper's one-step
controller (``--navigation off``). Prints the median and best step time (cells, navigation
stages, projection and control of the whole team, ``step_seconds``) and the median CPU
time of that step (all threads; other jobs on the machine do not stretch it), the loop's
time per step (with the noise draws and the recording; without the per-run results), the
whole run's wall and CPU time (set-up, and the per-run results tallied on every step: two
k-d tree passes over the million positions per state) and the process's peak resident
memory (one controller per process, so that the peak is its own).

Run: ``python benchmarks/million.py [--robots 1000000] [--steps 3] [--record-every 1] [--threads 2] [--navigation on|off]``;
the long run of the issue is ``--steps 100 --record-every 10`` (about 10 minutes on 2 idle
cores, most of it the per-step contact tally).
"""

from __future__ import annotations

import argparse
import resource
import time

import numba
import numpy as np
from _machine import machine
from avoidance_scale import circle_mapping
from vs_rvo2 import step_cpu_seconds

import robofleet
from robofleet.core.budget import memory_budget_set


def run(robots: int, steps: int, record_every: int, navigation: bool) -> dict:
    """One ``simulate`` run of the circle swap and its figures."""
    spec = robofleet.load_scenario({**circle_mapping(robots, steps, liveness=navigation), "record_every": record_every})
    t0, cpu0 = time.perf_counter(), time.process_time()
    with step_cpu_seconds() as step_cpu:
        trace = robofleet.simulate(spec, seed=0)
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    seconds = trace.arrays["step_seconds"]
    return {"median_step": float(np.median(seconds)), "best_step": float(seconds.min()), "step_cpu": float(np.median(step_cpu)),
            "loop": trace.metadata["loop_seconds"] / len(seconds), "wall": wall, "cpu": cpu, "kept_states": len(trace.positions),
            "collisions": trace.results["collisions"], "recorded_bytes": sum(a.nbytes for a in trace.arrays.values())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=1_000_000)
    ap.add_argument("--steps", type=int, default=3)
    ap.add_argument("--record-every", type=int, default=1)
    ap.add_argument("--threads", type=int, default=numba.get_num_threads())
    ap.add_argument("--memory-budget", default="8GiB", help="the recorder's memory budget for the run")
    ap.add_argument("--navigation", choices=["on", "off"], default="on",
                    help="on: B-UAVC as shipped (the default); off: the paper's one-step controller")
    args = ap.parse_args()
    navigation = args.navigation == "on"
    numba.set_num_threads(args.threads)
    print(machine())
    robofleet.simulate(robofleet.load_scenario(circle_mapping(5000, 2, liveness=navigation)), seed=0)  # load the compiled kernels
    with memory_budget_set(args.memory_budget):
        out = run(args.robots, args.steps, args.record_every, navigation)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    controller = "B-UAVC as shipped (navigation on)" if navigation else "the paper's controller (navigation off)"
    print(f"{args.robots:,} robots × {args.steps} steps, record_every {args.record_every}, {args.threads} thread(s), {controller}")
    print(f"  step (cells, navigation, projection, control): median {out['median_step']:.3f} s, best {out['best_step']:.3f} s; "
          f"CPU time (all threads) median {out['step_cpu']:.3f} s")
    print(f"  loop per step (noise, recording; without the result tally): {out['loop']:.3f} s")
    print(f"  whole run: {out['wall']:.1f} s ({out['cpu']:.1f} s CPU, all threads); states kept {out['kept_states']}, recorded arrays {out['recorded_bytes'] / 2**30:.2f} GiB; "
          f"colliding pairs {out['collisions']}")
    print(f"  peak RSS: {peak:.2f} GiB")


if __name__ == "__main__":
    main()
