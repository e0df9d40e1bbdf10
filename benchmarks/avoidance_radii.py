"""Robots of different radii and covariances: what the B-UAVC pair rule keeps, measured.

1. Exact estimates (Σ = 0), radii drawn per robot in [0.05, 0.5] m, random scenes in
   [-4, 4]² with two obstacles and adversarial desired velocities (half the robots chase
   their nearest neighbour, the others head for goals, some beyond the walls), 150 steps,
   through :class:`~robofleet.avoidance.SafetyFilter`; plus the simulation's own loop
   (``World.decide``, one-step controller and liveness rules) on a zero-noise three-box
   scenario with the cells' radii drawn per robot in [0.09, 0.45] m, 250 steps; plus 3-D
   cells (8 robots, radii in [0.05, 0.45] m, a 5 m box, each robot stepping at most
   v_max Δt towards the projection onto its cell of another robot's position or of a
   point beyond the walls), 200 steps. Printed:
   the smallest ``‖p_i − p_j‖ / (r_i + r_j)`` over all pairs, steps and runs, and the runs
   in which some pair came closer than ``r_i + r_j``.
2. The chance constraint in Monte Carlo under its premises: the estimates move with the
   filtered velocities and after every step each true position is drawn from
   ``N(p̂_i, Σ_i)`` (500 draws); contacts per close pair-step (estimates within
   ``r_i + r_j + 4(σ_i + σ_j)``), with the one-sided 95 % Clopper–Pearson upper bound, next
   to δ, for settings of unequal radii and covariances.

Run: ``python benchmarks/avoidance_radii.py [--runs 20] [--steps 400]`` (with the
sources of the tree to measure first on ``PYTHONPATH``).
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
from scipy.stats import beta

import robofleet
from robofleet.avoidance import CellGeometry, ObstacleSet, SafetyFilter, build_cells
from robofleet.avoidance.cell3d import project_onto_polytope, workspace_box_planes
from robofleet.avoidance.simulation import World
from robofleet.core import geometry

BOXES = [geometry.box_vertices(c, s, yaw=y) for c, s, y in (((-1.5, 1.0), (1.0, 0.6), 0.3), ((1.8, -1.2), (0.8, 1.2), -0.5))]


def place(rng, radii, half, obstacles, dim=2):
    """Positions at least ``r_i + r_j`` apart, inside the box and off the obstacles (rejection)."""
    p = np.full((len(radii), dim), np.nan)
    for i in np.argsort(-radii):
        while True:
            x = rng.uniform(-half + radii[i], half - radii[i], dim)
            placed = ~np.isnan(p[:, 0])
            if np.all(np.linalg.norm(p[placed] - x, axis=1) >= radii[placed] + radii[i] + 1e-3) and \
                    all(geometry.polygon_distance(x[None], o)[0] >= radii[i] + 1e-3 for o in obstacles):
                p[i] = x
                break
    return p


def worst_ratio(p, radii):
    i, j = np.triu_indices(len(p), 1)
    return float(np.min(np.linalg.norm(p[i] - p[j], axis=1) / (radii[i] + radii[j])))


def filter_run(seed: int, steps: int = 150) -> float:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 10))
    radii = rng.uniform(0.05, 0.5, n)
    p = place(rng, radii, 4.0, BOXES)
    f = SafetyFilter.create(n, radius=radii, dt=0.1, v_max=0.4, bounds=(-4, -4, 4, 4), obstacles=BOXES)
    goals, worst = rng.uniform(-5, 5, (n, 2)), np.inf
    for step in range(steps):
        if step % 40 == 0:
            goals = rng.uniform(-5, 5, (n, 2))
        d = np.linalg.norm(p[:, None] - p[None], axis=2) + np.eye(n) * 1e9
        chase = p[np.argmin(d, axis=1)] - p
        wanted = np.where((np.arange(n) + step // 40) % 2 == 0, chase.T, (goals - p).T).T
        desired = 1.2 * wanted / np.maximum(np.linalg.norm(wanted, axis=1, keepdims=True), 1e-12)
        p = p + f.filter(p, np.zeros((2, 2)), desired).velocity * f.dt
        worst = min(worst, worst_ratio(p, radii))
    return worst


def simulation_run(seed: int, steps: int = 250, r_max: float = 0.45) -> float:
    spec = robofleet.load_scenario({
        "family": "avoidance", "method": "buavc", "max_steps": steps, "delta": 0.1,
        "robots": {"n": 8, "sigma": 0.0, "radius": r_max, "layout": {"kind": "antipodal"}},
        "workspace": {"bounds": [-5, -5, 5, 5], "obstacles": [{"center": [-2, 1.5], "size": [1, 1]}, {"center": [2, -1], "size": [1.2, 0.8]},
                                                           {"center": [0, -3], "size": [1, 1]}]},
    })
    rng = np.random.default_rng(seed)
    world = World(spec, rng)
    radii = rng.uniform(0.2 * r_max, r_max, world.n)
    world.cell_model = replace(world.cell_model, radius=radii)
    shift, worst = np.zeros((world.n_obstacles, 2)), np.inf
    for _ in range(steps):
        _, u, _ = world.decide(world.positions(), shift)
        world.advance(u)
        worst = min(worst, worst_ratio(world.positions(), radii))
    return worst


def run_3d(seed: int, steps: int = 200) -> float:
    rng = np.random.default_rng(100 + seed)
    n, half, step_length = 8, 2.5, 0.05
    radii = rng.uniform(0.05, 0.45, n)
    p = place(rng, radii, half, (), dim=3)
    no_boxes = ObstacleSet(np.zeros((0, 1, 3)), np.zeros((0, 3, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    geo = CellGeometry(no_boxes, *workspace_box_planes(np.full(3, -half), np.full(3, half)))
    worst = np.inf
    for step in range(steps):
        goals = p[rng.permutation(n)] if step % 20 < 10 else rng.uniform(-half - 1, half + 1, (n, 3))
        cells = build_cells(p, np.zeros((n, 3, 3)), radii, 1.6, geo, 2.0)
        target, ok = project_onto_polytope(goals, cells.A, cells.b, cells.valid)
        move = np.where(ok[:, None], target - p, 0.0)
        p = p + move * np.minimum(1.0, step_length / np.maximum(np.linalg.norm(move, axis=1, keepdims=True), 1e-300))
        worst = min(worst, worst_ratio(p, radii))
    return worst


def upper_95(contacts: int, trials: int) -> float:
    return 1.0 if trials == 0 or contacts == trials else float(beta.ppf(0.95, contacts + 1, trials - contacts))


def chance(rng, delta, radii, covs, p, desired, steps, samples=500) -> tuple[int, int]:
    f = SafetyFilter.create(len(p), radius=radii, dt=0.1, v_max=0.4, delta=delta, bounds=(-3, -3, 3, 3))
    n = len(p)
    i, j = np.triu_indices(n, 1)
    factor = np.linalg.cholesky(covs + 1e-300 * np.eye(2))
    sigma = np.sqrt(np.linalg.eigvalsh(covs).max(axis=1))
    contacts = trials = 0
    for step in range(steps):
        p = p + f.filter(p, covs, desired(p, step)).velocity * f.dt
        close = np.linalg.norm(p[i] - p[j], axis=1) < radii[i] + radii[j] + 4 * (sigma[i] + sigma[j])
        if close.any():
            truth = p[None] + np.einsum("nij,snj->sni", factor, rng.standard_normal((samples, n, 2)))
            gap = np.linalg.norm(truth[:, i[close]] - truth[:, j[close]], axis=2)
            contacts += int((gap < radii[i[close]] + radii[j[close]]).sum())
            trials += gap.size
    return contacts, trials


def chance_settings():
    def crowd(rng):
        n = 8
        radii = rng.uniform(0.1, 0.4, n)
        covs = []
        for _ in range(n):
            a = rng.uniform(0, np.pi)
            rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
            covs.append(rot @ np.diag(rng.uniform(0.02, 0.12, 2) ** 2) @ rot.T)
        angle = np.arange(n) * 2 * np.pi / n
        return 0.1, radii, np.array(covs), 2.5 * np.column_stack([np.cos(angle), np.sin(angle)]), \
            lambda q, s: -q + 0.3 * np.sin(0.05 * s + np.arange(n))[:, None]

    def head_on(radii):
        return lambda rng: (0.1, np.array(radii), np.array([0.03**2 * np.eye(2), 0.1**2 * np.eye(2)]),
                            np.array([[-1.5, 0.0], [1.5, 0.0]]), lambda q, s: q[::-1] - q)

    def wall(rng):
        return (0.05, np.array([0.1, 0.45]), np.array([0.08**2 * np.eye(2), 0.03**2 * np.eye(2)]), np.array([[0.0, 0.3], [2.3, 0.0]]),
                lambda q, s: np.array([q[1] - q[0], [1.0, 0.1 * np.sin(0.1 * s)]]))

    return {
        "head-on, r 0.2/0.2 m, σ 0.03/0.10 m": head_on((0.2, 0.2)),
        "head-on, r 0.1/0.4 m, σ 0.03/0.10 m": head_on((0.1, 0.4)),
        "head-on, r 0.4/0.1 m, σ 0.03/0.10 m": head_on((0.4, 0.1)),
        "small r 0.1 m σ 0.08 m pushes large r 0.45 m σ 0.03 m against a wall": wall,
        "crowd of 8, r 0.1–0.4 m, rotated Σ of σ 0.02–0.12 m, pushing to the centre": crowd,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--steps", type=int, default=400, help="steps of each Monte Carlo setting (0: skip them)")
    args = parser.parse_args()
    print(f"exact estimates, {args.runs} runs each (seeds 0..{args.runs - 1}):")
    for name, run in (("SafetyFilter, random scenes", filter_run), ("simulation loop, three boxes", simulation_run), ("3-D cells", run_3d)):
        ratios = np.array([run(seed) for seed in range(args.runs)])
        print(f"  {name}: min ‖p_i − p_j‖/(r_i + r_j) = {ratios.min():.12f}; runs below 1 − 1e-9: {int((ratios < 1 - 1e-9).sum())}/{args.runs}")
    if args.steps == 0:
        return
    print(f"chance constraint, {args.steps} steps × 500 draws, contacts per close pair-step:")
    for name, make in chance_settings().items():
        rng = np.random.default_rng(21)
        delta, radii, covs, p, desired = make(rng)
        contacts, trials = chance(rng, delta, radii, covs, p, desired, args.steps)
        rate = contacts / trials if trials else float("nan")
        print(f"  {name}: {contacts}/{trials} = {rate:.4f} (95 % upper {upper_95(contacts, trials):.4f}) vs δ = {delta}")


if __name__ == "__main__":
    main()
