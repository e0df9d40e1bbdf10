"""A naive go-to-goal policy made safe by the B-UAVC safety filter.

Every robot of a circle swap drives straight at its goal (``u = v_max · unit(g − p̂)``),
which makes them all meet in the middle. Run once without and once with
:class:`robofleet.avoidance.SafetyFilter` (with its deadlock memory: a robot that makes no
progress towards what it asks for turns its request by −90° for a few steps, appendix C);
estimates are noisy (``N(0, σ² I)``) and contacts are judged on the true positions.

Run:  python examples/safety_filter_go_to_goal.py [--robots 12] [--steps 400] [--seed 0]
"""

from __future__ import annotations

import argparse

import numpy as np

from robofleet.avoidance import SafetyFilter
from robofleet.avoidance.navigation.progress import DeadlockParams
from robofleet.core.metrics import pair_contacts

RADIUS, V_MAX, DT, SIGMA = 0.2, 0.4, 0.1, 0.05


def go_to_goal(estimates: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """The naive policy: full speed straight at the goal, slowing down on the last step."""
    delta = goals - estimates
    dist = np.linalg.norm(delta, axis=1, keepdims=True)
    return delta / np.maximum(dist, 1e-9) * np.minimum(V_MAX, dist / DT)


def run(n: int, steps: int, seed: int, safe: bool) -> tuple[int, float]:
    """Contacts (pair-steps) and the share of robots within 0.1 m of their goal at the end."""
    rng = np.random.default_rng(seed)
    angles = 2 * np.pi * np.arange(n) / n
    positions = 4.0 * np.column_stack([np.cos(angles), np.sin(angles)])
    goals = -positions
    cov = SIGMA**2 * np.eye(2)
    shield = SafetyFilter.create(n, radius=RADIUS, dt=DT, v_max=V_MAX, delta=0.1, bounds=(-5, -5, 5, 5),
                                  deadlock=DeadlockParams())
    contacts = 0
    for _ in range(steps):
        estimates = positions + rng.normal(0.0, SIGMA, positions.shape)
        u = go_to_goal(estimates, goals)
        if safe:
            u = shield.filter(estimates, cov, u).velocity
        positions = positions + u * DT
        contacts += len(pair_contacts(positions[None], RADIUS)[0])
    arrived = float(np.mean(np.linalg.norm(positions - goals, axis=1) < 0.1))
    return contacts, arrived


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=12)
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for safe in (False, True):
        contacts, arrived = run(args.robots, args.steps, args.seed, safe)
        label = "filtered  " if safe else "unfiltered"
        print(f"{label}: {contacts} contact pair-steps, {arrived:.0%} of robots at their goal after {args.steps} steps")


if __name__ == "__main__":
    main()
