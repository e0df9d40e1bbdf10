"""Dense crowd swap (``scenarios/avoidance/crowd_swap.yaml``): every robot home within the
budget, contacts per close pair-step against δ, and the premise of the chance constraint.

N robots fill both halves of a walled room on a 1 m grid and swap sides (the ``halves``
layout, :mod:`robofleet.avoidance.placement`). The shipped file has 200 robots in a
24 × 10 m room (10 of the 12 columns of each half filled); ``--robots`` scales the room so
that the density and the free share stay the same: ``round(10 √(N/200))`` rows,
``⌈N / (2 rows)⌉`` filled columns per half out of ``⌈1.2 ×⌉`` that many. The step budget
follows the shipped straight-line rule (4 × the longest straight-line travel time,
:func:`robofleet.avoidance.spec.straight_line_budget`) unless ``--max-steps`` caps it.

Prints, per size: robots home at the end (their arrival latched and the run's verdict),
the time the last robot arrived, contacts among close pair-steps (centres under 1 m) with
the one-sided 95 % Clopper–Pearson upper bound of their rate next to δ, robot–wall
contacts, the share of robot-steps (robots not yet arrived) whose estimate lay in its own
cell, and the loop's wall time and median step.

Run: ``python benchmarks/crowd_swap.py [--robots 200 2000] [--seed 0] [--max-steps N] [--navigation on|off|spec] [--method buavc]``
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from _machine import machine
from scipy.stats import beta

import robofleet
from robofleet.avoidance.spec import straight_line_budget
from robofleet.core import metrics

SPACING = 1.0


def room(n: int) -> list[float]:
    """The room ``[xmin, ymin, xmax, ymax]`` of ``n`` robots (module docstring)."""
    rows = max(1, round(10 * math.sqrt(n / 200)))
    filled = math.ceil(n / 2 / rows)
    columns = math.ceil(1.2 * filled)
    return [-SPACING * columns, -SPACING * rows / 2, SPACING * columns, SPACING * rows / 2]


def scenario(n: int, max_steps: int | None, navigation: str, method: str):
    box = room(n)
    overrides = {"robots.n": n, "workspace.bounds": box, "robots.layout.box": box, "method": method}
    if navigation != "spec":
        overrides["navigation.enabled"] = navigation == "on"
    spec = robofleet.load_scenario("avoidance/crowd_swap", overrides)
    steps = straight_line_budget(spec) if max_steps is None else max_steps
    return robofleet.load_scenario("avoidance/crowd_swap", {**overrides, "max_steps": steps})


def upper_bound(k: int, n: int, level: float = 0.95) -> float:
    """One-sided Clopper–Pearson upper bound of a rate of ``k`` events in ``n`` trials."""
    return 1.0 if k >= n else float(beta.ppf(level, k + 1, n - k))


def report(n: int, spec, seed: int) -> str:
    t0 = time.perf_counter()
    trace = robofleet.simulate(spec, seed=seed)
    wall = time.perf_counter() - t0
    r, arrays = trace.results, trace.arrays
    positions = arrays["positions"]
    goals = np.asarray(trace.metadata["goals"])
    close = int(r["close_pair_steps"])
    contacts = int(round(r["close_pair_step_rate"] * close)) if close else 0
    walls = int(np.count_nonzero(spec.workspace.build().boundary_distance(positions) < spec.robots.radius - metrics.CONTACT_TOL))
    arrived = arrays["arrival_steps"] >= 0
    true_gap = np.linalg.norm(positions[-1] - goals, axis=1)
    last = f"{arrays['arrival_steps'].max() * spec.dt:.0f} s" if arrived.all() else "—"
    return (f"| {n} | {spec.max_steps} steps = {spec.max_steps * spec.dt:.0f} s | {int(positions.shape[0]) - 1} | {100 * arrived.mean():.1f} % "
            f"({'success' if r['success'] else 'not all home'}) | {last} | {np.median(true_gap[arrived]) if arrived.any() else float('nan'):.3f} / "
            f"{true_gap.max():.2f} m | {contacts} / {close:,} | {upper_bound(contacts, close):.1e} (δ = {spec.delta}) | {walls} | "
            f"{100 * r['estimate_in_cell_share']:.1f} % | {wall:.0f} s, {1e3 * r['median_step_seconds']:.1f} ms |")


HEADER = ("| robots | budget | steps run | robots arrived | last arrival | true distance to goal, median / max | "
          "contacts / close pair-steps | contact rate, one-sided 95 % upper | wall contacts | estimate in own cell | wall time, median step |\n"
          "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[200])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-steps", type=int, default=None, help="cap the step budget (default: the straight-line rule)")
    ap.add_argument("--navigation", choices=["on", "off", "spec"], default="spec", help="the navigation rules (spec: as shipped)")
    ap.add_argument("--method", default="buavc")
    args = ap.parse_args()
    print(machine())
    print(HEADER)
    for n in args.robots:
        print(report(n, scenario(n, args.max_steps, args.navigation, args.method), args.seed), flush=True)


if __name__ == "__main__":
    main()
