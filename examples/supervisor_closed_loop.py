"""Robots executing a plan under an online RMTRACK supervisor, with late and lost reports.

`robofleet.coordination.Supervisor` decides from what the robots report: each robot
reports its plan step every tick, but a report arrives 0-5 ticks late or not at all
(``--loss``), and robots are delayed at random (they fail a step with probability
``--delay``). A robot advances only up to the ``until`` of the answers it received. The
supervisor's guarantee (docs/theory/coordination.md): late information only makes robots
wait, so no two robots come closer than 2r and, with the deadlock check, all finish.

Run:  python examples/supervisor_closed_loop.py [--seed 0] [--loss 0.2] [--delay 0.3]
"""

from __future__ import annotations

import argparse

import numpy as np

import robofleet
from robofleet.coordination import Supervisor


def closed_loop(seed: int, loss: float, delay: float, max_ticks: int = 20_000) -> tuple[int, float, bool]:
    """Ticks until every robot is done, the smallest distance between robots, whether all finished."""
    spec = robofleet.load_scenario("coordination/x_corridor_5_tff")
    sup = Supervisor.from_scenario(spec, seed=seed)
    plan, rng = sup.traj, np.random.default_rng(seed)
    n = plan.n_robots
    progress, permitted = np.zeros(n, int), np.zeros(n, int)
    in_flight: list[tuple[int, int, int]] = []  # (arrival tick, robot, reported step)
    closest = np.inf
    for tick in range(max_ticks):
        for i in range(n):
            if rng.random() >= loss:
                in_flight.append((tick + int(rng.integers(0, 6)), i, int(progress[i])))
        arrived = [report for report in in_flight if report[0] <= tick]
        in_flight = [report for report in in_flight if report[0] > tick]
        for _, i, step in arrived:
            sup.report(i, progress=step)
        for i in range(n):
            answer = sup.answer(i)
            if answer.action == "go":
                permitted[i] = max(permitted[i], answer.until)
        moving = (progress < permitted) & (rng.random(n) >= delay)
        progress[moving] += 1
        points = plan.positions[np.arange(n), progress]
        gaps = np.linalg.norm(points[:, None] - points[None], axis=-1) + np.diag(np.full(n, np.inf))
        closest = min(closest, float(gaps.min()))
        if np.all(progress >= plan.lengths):
            return tick + 1, closest, True
    return max_ticks, closest, False


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--loss", type=float, default=0.2)
    parser.add_argument("--delay", type=float, default=0.3)
    args = parser.parse_args()
    ticks, closest, finished = closed_loop(args.seed, args.loss, args.delay)
    radius = robofleet.load_scenario("coordination/x_corridor_5_tff").robots.radius
    print(f"all robots done: {finished} after {ticks} ticks; closest pair {closest:.1f} (2r = {2 * radius:g})")


if __name__ == "__main__":
    main()
