"""Throughput of the single-integrator B-UAVC step on the circle swap at scale.

Robots sit on a circle whose radius grows with N so the spacing stays 4 r_s (neighbours
found on a uniform grid, no O(N²) loop). Prints time per step and robot-steps per second
over the first ``--steps`` steps (the whole team's cell construction + projection +
control, as measured inside the simulation loop), and the growth factor between sizes
with the one N log N predicts (×13.3 from 1k to 10k, ×5.9 from 10k to 50k), the whole
loop's time per step including the noise draws and the recording of the arrays
(``trace.metadata["loop_seconds"]``), and the whole ``simulate`` call per step, which
adds the set-up and the per-run results of :mod:`robofleet.avoidance.metrics` (pair
contacts on every recorded state).

The kernels run on numba's threads (``--threads``, default all; see
:mod:`robofleet.avoidance.kernels`). ``--liveness`` runs B-UAVC as shipped (the navigation
stages on); ``--clock cpu`` times the step in CPU time of the process (all threads) instead
of wall time; ``--boxes K`` replaces the circle by the shipped ten-box layout
(``scenarios/avoidance/ten_boxes.yaml``) scaled K times (workspace and box centres; the
boxes stay 1 × 1 m), the robots drawn on its antipodal ring, radius 4.7 K m.

Run: ``python benchmarks/avoidance_scale.py [--sizes 100 1000 10000] [--steps 30] [--threads 1] [--liveness] [--clock wall|cpu] [--boxes K]``
"""

from __future__ import annotations

import argparse
import math
import resource
import time

from pathlib import Path

import numba
import numpy as np
import yaml
from _machine import machine, nlogn_growth
from vs_rvo2 import step_cpu_seconds

import robofleet

TEN_BOXES = Path(__file__).resolve().parents[1] / "scenarios" / "avoidance" / "ten_boxes.yaml"


def circle_mapping(n: int, steps: int, method: str = "buavc", liveness: bool = False) -> dict:
    radius = max(4.0, n * 4 * 0.2 / (2 * math.pi))
    half = radius + 2.0
    return {
        "family": "avoidance", "name": f"circle-{n}", "method": method, "max_steps": steps,
        "workspace": {"bounds": [-half, -half, half, half]},
        "robots": {"n": n, "radius": 0.2, "v_max": 0.4, "sigma": 0.1, "layout": {"kind": "circle", "radius": radius}},
        "record_cells": False, "navigation": {"enabled": liveness},
    }


def boxes_mapping(n: int, steps: int, scale: float, method: str = "buavc", liveness: bool = False) -> dict:
    """The shipped ten-box layout scaled ``scale`` times (module docstring) with ``n`` robots."""
    mapping = yaml.safe_load(TEN_BOXES.read_text())
    ws = mapping["workspace"]
    ws["bounds"] = [scale * v for v in ws["bounds"]]
    ws["obstacles"] = [{**box, "center": [scale * c for c in box["center"]]} for box in ws["obstacles"]]
    layout = {**mapping["robots"]["layout"], "r_max": scale * mapping["robots"]["layout"]["r_max"]}
    return {**mapping, "name": f"ten-boxes-x{scale:g}-{n}", "method": method, "max_steps": steps, "record_cells": False,
            "robots": {**mapping["robots"], "n": n, "layout": layout}, "navigation": {"enabled": liveness}}


def measure(n: int, steps: int, method: str, repeat: int, liveness: bool = False, clock: str = "wall",
            boxes: float | None = None) -> tuple[float, float, float]:
    """Median algorithm time per step (cells + controller of the whole team; CPU time with
    ``clock="cpu"``), the whole loop's wall time per step (noise draws and recording
    included) and the whole ``simulate`` call's time per step (set-up and per-run results
    included); each the best of ``repeat`` runs (the first run of a process also compiles
    the kernels)."""
    mapping = circle_mapping(n, steps, method, liveness) if boxes is None else boxes_mapping(n, steps, boxes, method, liveness)
    spec = robofleet.load_scenario(mapping)
    figures = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        with step_cpu_seconds() as cpu:
            trace = robofleet.simulate(spec, seed=0)
        taken = len(trace.arrays["step_seconds"])
        run = (time.perf_counter() - t0) / taken
        step = float(np.median(cpu if clock == "cpu" else trace.arrays["step_seconds"]))
        figures.append((step, trace.metadata["loop_seconds"] / taken, run))
    return tuple(min(column) for column in zip(*figures))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10000])
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--method", default="buavc")
    ap.add_argument("--repeat", type=int, default=3, help="runs per size; the best is shown")
    ap.add_argument("--threads", type=int, default=numba.get_num_threads())
    ap.add_argument("--liveness", action="store_true", help="with the default liveness rules (off: the paper's controller)")
    ap.add_argument("--clock", choices=["wall", "cpu"], default="wall", help="time the step in wall or CPU time")
    ap.add_argument("--boxes", type=float, default=None, metavar="K", help="the ten-box layout scaled K times instead of the circle")
    args = ap.parse_args()
    numba.set_num_threads(args.threads)
    print(machine())
    print(f"liveness rules {'on' if args.liveness else 'off (the paper controller, appendix C)'}; "
          f"{'circle swap' if args.boxes is None else f'ten boxes scaled ×{args.boxes:g}'}; step in {args.clock} time")
    print(f"{'robots':>8} {'ms/step':>10} {'robot-steps/s':>15} {'growth':>8} {'N log N':>8} {'loop ms/step':>13} {'run ms/step':>12}")
    prev = None
    for n in args.sizes:
        sec, loop, run = measure(n, args.steps, args.method, args.repeat, args.liveness, args.clock, args.boxes)
        growth = f"×{sec / prev[1]:.1f}" if prev else ""
        ref = f"×{nlogn_growth(prev[0], n):.1f}" if prev else ""
        print(f"{n:>8} {sec * 1e3:>10.2f} {n / sec:>15,.0f} {growth:>8} {ref:>8} {loop * 1e3:>13.2f} {run * 1e3:>12.2f}", flush=True)
        prev = (n, sec)
    print(f"peak RSS: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20:.2f} GiB")


if __name__ == "__main__":
    main()
