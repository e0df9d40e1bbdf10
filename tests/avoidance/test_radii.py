"""Robots of different radii (per robot, drawn per robot): each pair keeps ``r_i + r_j``.

The rule (:mod:`robofleet.avoidance.cell`): both robots of a pair keep the mean radius
``(r_i + r_j)/2`` from their common plane, each with its own chance buffer. With exact
estimates, pair distances of at least ``r_i + r_j`` are an invariant of every closed loop
whose steps end on a segment towards a cell point (or hold still) — checked here in random
cluttered scenes with adversarial desired velocities, through the batch filter, the
per-robot filter, the simulation's controller and 3-D cells. The chance constraint with
unequal radii and covariances is checked in Monte Carlo against δ with a one-sided 95 %
bound; the three builders of the rows (compiled shared-Σ kernel, pairwise form, one
robot's own view) agree.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import beta

import robofleet
from robofleet.avoidance import CellGeometry, ObstacleSet, RobotSafetyFilter, SafetyFilter, build_cells, cell_from_view, wall_planes
from robofleet.avoidance.cell import _obstacle_rows, _pad, _robot_rows, _wall_rows, neighbour_pairs
from robofleet.avoidance.cell3d import project_onto_polytope, workspace_box_planes
from robofleet.avoidance.simulation import World
from robofleet.core import geometry

TOL = 1e-9
HALF = 4.0  # the scenes' workspace [-4, 4]²
BOXES = [geometry.box_vertices(c, s, yaw=y) for c, s, y in (((-1.5, 1.0), (1.0, 0.6), 0.3), ((1.8, -1.2), (0.8, 1.2), -0.5))]


# ---------------------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------------------
def place(rng, radii, half, obstacles=(), dim=2, attempts=20_000):
    """Positions at least ``r_i + r_j`` apart, ``r_i`` inside the box ``[-half, half]^dim``
    and ``r_i`` from every obstacle polygon (rejection sampling, largest robots first)."""
    p = np.full((len(radii), dim), np.nan)
    for i in np.argsort(-radii):
        for _ in range(attempts):
            x = rng.uniform(-half + radii[i], half - radii[i], dim)
            placed = ~np.isnan(p[:, 0])
            if np.all(np.linalg.norm(p[placed] - x, axis=1) >= radii[placed] + radii[i] + 1e-3) and \
                    all(geometry.polygon_distance(x[None, :2], o)[0] >= radii[i] + 1e-3 for o in obstacles):
                p[i] = x
                break
        else:
            raise AssertionError("scene too crowded")
    return p


def pair_margin(p, radii):
    """min over pairs of ``‖p_i − p_j‖ − (r_i + r_j)``."""
    i, j = np.triu_indices(len(p), 1)
    return float(np.min(np.linalg.norm(p[i] - p[j], axis=1) - (radii[i] + radii[j])))


def obstacle_margin(p, radii, obstacles):
    """min over robots of the distance to the obstacles and walls minus ``r_i``."""
    wall = HALF - np.abs(p).max(axis=1) - radii
    gaps = [geometry.polygon_distance(p, o) - radii for o in obstacles]
    return float(np.min([wall.min(), *(g.min() for g in gaps)]))


def adversarial_desired(rng, p, goals, v_max, step):
    """Desired velocities that push: half the robots chase their nearest neighbour, the
    others head for goals (re-drawn now and then, some beyond the walls)."""
    d = np.linalg.norm(p[:, None] - p[None], axis=2) + np.eye(len(p)) * 1e9
    chase = p[np.argmin(d, axis=1)] - p
    wanted = np.where((np.arange(len(p)) + step // 40) % 2 == 0, chase.T, (goals - p).T).T
    return 3.0 * v_max * wanted / np.maximum(np.linalg.norm(wanted, axis=1, keepdims=True), 1e-12)


# ---------------------------------------------------------------------------------------
# (a) exact estimates: pairs never closer than r_i + r_j
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("small, large, angle", [(0.1, 0.5, 0.0), (0.05, 0.6, 0.7), (0.2, 0.35, -1.1), (0.1, 0.5, 1.45)])
def test_a_small_robot_driving_at_a_large_one_parked_at_a_wall_keeps_the_radii_sum(small, large, angle):
    """The large robot presses against the right wall, the small one drives straight at it:
    the small one stops ``r_small + r_large`` away (each robot keeping its own radius from
    the bisector let it in to ``2 r_small``)."""
    f = SafetyFilter.create(2, radius=[small, large], dt=0.1, v_max=0.4, bounds=(-3, -3, 3, 3))
    wall_point = np.array([3.0 - large, 0.0])
    p = np.array([wall_point - 2.0 * np.array([np.cos(angle), np.sin(angle)]), wall_point])
    closest = np.inf
    for _ in range(150):
        push = np.array([wall_point + [large, 0.0] - p[0], [1.0, 0.0]])
        p = p + f.filter(p, np.zeros((2, 2)), push).velocity * f.dt
        closest = min(closest, np.linalg.norm(p[1] - p[0]))
    assert closest >= small + large - TOL
    assert closest <= small + large + 0.05  # it did drive up to the large one


@pytest.mark.parametrize("seed, face", [(seed, "batch") for seed in range(6)] + [(seed, "per_robot") for seed in range(3)])
def test_random_scenes_with_per_robot_radii_keep_every_pair_apart(seed, face):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 10))
    radii = rng.uniform(0.05, 0.5, n)
    p = place(rng, radii, HALF, BOXES)
    options = {"dt": 0.1, "v_max": 0.4, "bounds": (-HALF, -HALF, HALF, HALF), "obstacles": BOXES, "local_box": 2.0}
    fleet = SafetyFilter.create(n, radius=radii, **options)
    robots = [RobotSafetyFilter.create(radius=r, **options) for r in radii]
    goals = rng.uniform(-5, 5, (n, 2))
    worst_pair, worst_obstacle = np.inf, np.inf
    for step in range(150 if face == "batch" else 80):
        if step % 40 == 0:
            goals = rng.uniform(-5, 5, (n, 2))
        desired = adversarial_desired(rng, p, goals, 0.4, step)
        if face == "batch":
            u = fleet.filter(p, np.zeros((2, 2)), desired).velocity
        else:
            others = [np.delete(np.arange(n), i) for i in range(n)]
            u = np.array([robots[i].filter(p[i], np.zeros((2, 2)), desired[i], p[o], neighbour_radii=radii[o]).velocity[0]
                          for i, o in enumerate(others)])
        p = p + u * 0.1
        worst_pair = min(worst_pair, pair_margin(p, radii))
        worst_obstacle = min(worst_obstacle, obstacle_margin(p, radii, BOXES))
    assert worst_pair >= -TOL and worst_obstacle >= -TOL


def mixed_radius_world(seed, n=8, r_max=0.45):
    """A zero-noise single-integrator scenario with three boxes; the cells' radii are then
    drawn per robot in [0.2 r_max, r_max] (the layout keeps starts 2 r_max apart)."""
    spec = robofleet.load_scenario({
        "family": "avoidance", "method": "buavc", "max_steps": 300, "delta": 0.1,
        "robots": {"n": n, "sigma": 0.0, "radius": r_max, "layout": {"kind": "antipodal"}},
        "workspace": {"bounds": [-5, -5, 5, 5], "obstacles": [{"center": [-2, 1.5], "size": [1, 1]}, {"center": [2, -1], "size": [1.2, 0.8]},
                                                           {"center": [0, -3], "size": [1, 1]}]},
    })
    rng = np.random.default_rng(seed)
    world = World(spec, rng)
    radii = rng.uniform(0.2 * r_max, r_max, world.n)
    world.cell_model = replace(world.cell_model, radius=radii)
    return world, radii


@pytest.mark.parametrize("seed", range(3))
def test_the_simulation_keeps_pairs_of_mixed_radii_apart(seed):
    """The simulation's own loop (one-step controller, liveness rules, deadlock heuristic)
    with per-robot radii and exact estimates."""
    world, radii = mixed_radius_world(seed)
    shift = np.zeros((world.n_obstacles, 2))
    worst = np.inf
    for _ in range(250):
        p = world.positions()
        _, u, _ = world.decide(p, shift)
        world.advance(u)
        worst = min(worst, pair_margin(world.positions(), radii))
    assert worst >= -TOL


@pytest.mark.parametrize("seed", range(3))
def test_3d_cells_keep_pairs_of_mixed_radii_apart(seed):
    """3-D cells (pairwise rows) in a box: every robot steps towards the projection of its
    goal onto its cell (at most v_max Δt), exact estimates; goals are other robots'
    positions half the time."""
    rng = np.random.default_rng(100 + seed)
    n, half, dt, v_max = 8, 2.5, 0.1, 0.5
    radii = rng.uniform(0.05, 0.45, n)
    p = place(rng, radii, half, dim=3)
    walls = workspace_box_planes(np.full(3, -half), np.full(3, half))
    geo = CellGeometry(ObstacleSet(np.zeros((0, 1, 3)), np.zeros((0, 3, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))), *walls)
    worst = np.inf
    for step in range(200):
        goals = p[rng.permutation(n)] if step % 20 < 10 else rng.uniform(-half - 1, half + 1, (n, 3))
        cells = build_cells(p, np.zeros((n, 3, 3)), radii, 1.6, geo, 2.0)
        target, ok = project_onto_polytope(goals, cells.A, cells.b, cells.valid)
        move = np.where(ok[:, None], target - p, 0.0)
        length = np.linalg.norm(move, axis=1, keepdims=True)
        p = p + move * np.minimum(1.0, v_max * dt / np.maximum(length, 1e-300))
        worst = min(worst, pair_margin(p, radii))
    assert worst >= -TOL


# ---------------------------------------------------------------------------------------
# (b) the chance constraint with unequal radii and covariances, in Monte Carlo
# ---------------------------------------------------------------------------------------
def random_covariance(rng, low, high):
    angle = rng.uniform(0, np.pi)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    return rot @ np.diag(rng.uniform(low, high, 2) ** 2) @ rot.T


def chance_loop(rng, f, p, covs, radii, desired, steps, samples):
    """The premises of Sec. 4 taken literally: the estimates move with the filtered
    velocities, and after every step each robot's true position is drawn from
    ``N(p̂_i, Σ_i)`` (``samples`` draws). Returns (contacts, trials) over the close pair-steps
    (estimates within ``r_i + r_j + 4(σ_i + σ_j)``) — all of them, whether or not the
    estimates lay in their cells (stronger than the guarantee, which assumes they did)."""
    n = len(p)
    i, j = np.triu_indices(n, 1)
    factor = np.linalg.cholesky(covs + 1e-300 * np.eye(2))
    sigma = np.sqrt(np.linalg.eigvalsh(covs).max(axis=1))
    contacts = trials = 0
    for step in range(steps):
        p = p + f.filter(p, covs, desired(p, step)).velocity * f.dt
        close = np.linalg.norm(p[i] - p[j], axis=1) < radii[i] + radii[j] + 4 * (sigma[i] + sigma[j])
        if not close.any():
            continue
        truth = p[None] + np.einsum("nij,snj->sni", factor, rng.standard_normal((samples, n, 2)))
        gap = np.linalg.norm(truth[:, i[close]] - truth[:, j[close]], axis=2)
        contacts += int((gap < radii[i[close]] + radii[j[close]]).sum())
        trials += gap.size
    return contacts, trials


def upper_95(contacts, trials):
    """One-sided 95 % (Clopper–Pearson) upper bound of a rate."""
    return 1.0 if contacts == trials else float(beta.ppf(0.95, contacts + 1, trials - contacts))


def setting_crowd(rng):
    """Eight robots of radii 0.1–0.4 m and anisotropic Σ (σ 0.02–0.12 m) pushing to the centre."""
    n = 8
    radii = rng.uniform(0.1, 0.4, n)
    covs = np.array([random_covariance(rng, 0.02, 0.12) for _ in range(n)])
    angle = np.arange(n) * 2 * np.pi / n
    p = 2.5 * np.column_stack([np.cos(angle), np.sin(angle)])
    centre = lambda q, step: -q + 0.3 * np.sin(0.05 * step + np.arange(n))[:, None]  # noqa: E731
    return 0.1, radii, covs, p, centre


def head_on(radii):
    def setting(rng):
        """A well-localised robot (σ 0.03 m) and a noisy one (σ 0.1 m) driven head-on at
        each other (with appendix B's centre-based offset the first one sat outside its
        cell while they pressed, and 16 % of these steps touched for radii 0.2/0.2 m)."""
        covs = np.array([0.03**2 * np.eye(2), 0.1**2 * np.eye(2)])
        p = np.array([[-1.5, 0.0], [1.5, 0.0]])
        return 0.1, np.array(radii), covs, p, lambda q, step: q[::-1] - q
    setting.__name__ = f"head_on_{radii[0]}_{radii[1]}"
    return setting


def setting_wall(rng):
    """A small noisy robot (r 0.1 m, σ 0.08 m) pushing a large, better-localised one
    (r 0.45 m, σ 0.03 m) against a wall."""
    radii = np.array([0.1, 0.45])
    covs = np.array([0.08**2 * np.eye(2), 0.03**2 * np.eye(2)])
    p = np.array([[0.0, 0.3], [2.3, 0.0]])
    push = lambda q, step: np.array([q[1] - q[0], [1.0, 0.1 * np.sin(0.1 * step)]])  # noqa: E731
    return 0.05, radii, covs, p, push


@pytest.mark.parametrize("setting", [setting_crowd, head_on((0.2, 0.2)), head_on((0.1, 0.4)), head_on((0.4, 0.1)), setting_wall], ids=lambda s: s.__name__)
def test_contact_rate_per_close_pair_step_is_at_most_delta(setting):
    rng = np.random.default_rng(21)
    delta, radii, covs, p, desired = setting(rng)
    f = SafetyFilter.create(len(p), radius=radii, dt=0.1, v_max=0.4, delta=delta, bounds=(-3, -3, 3, 3))
    contacts, trials = chance_loop(rng, f, p, covs, radii, desired, steps=200, samples=200)
    assert trials > 20_000  # the pairs did press on each other
    assert upper_95(contacts, trials) <= delta


# ---------------------------------------------------------------------------------------
# (c) the builders agree: compiled shared-Σ kernel, pairwise form, one robot's own view
# ---------------------------------------------------------------------------------------
def row_key(A, b):
    rows = np.round(np.column_stack([A, b]), 8)
    return rows[np.lexsort(rows.T[::-1])]


def geometry_2d():
    obstacles = ObstacleSet.build(BOXES, np.repeat((0.05**2 * np.eye(2))[None], len(BOXES), 0), 0.05)
    return CellGeometry(obstacles, *wall_planes(np.array([[-5.0, -5.0], [5.0, -5.0], [5.0, 5.0], [-5.0, 5.0]])))


@pytest.mark.parametrize("seed", range(4))
def test_the_three_builders_agree_with_per_robot_radii(seed):
    rng = np.random.default_rng(seed)
    n = 60
    p = rng.uniform(-4.5, 4.5, (n, 2))
    radii = rng.uniform(0.05, 0.5, n)
    geo = geometry_2d()
    shared = np.broadcast_to(random_covariance(rng, 0.02, 0.1), (n, 2, 2))
    own = np.array([random_covariance(rng, 0.0, 0.1) for _ in range(n)])
    for covs in (shared, own):
        batch = build_cells(p, covs, radii, 1.6, geo, 2.0)  # the compiled kernel for the shared Σ
        pairwise = _pad(n, 2, [_robot_rows(p, covs, radii, 1.6, neighbour_pairs(p, 2.0)), _obstacle_rows(p, covs, radii, 1.6, geo.obstacles, 2.0),
                               _wall_rows(p, covs, radii, 1.6, geo, 2.0)])
        for i in range(n):
            others = np.delete(np.arange(n), i)
            A, b, _ = cell_from_view(p[i], covs[i], radii[i], p[others], covs[others], 1.6, geo, 2.0, neighbour_radii=radii[others])
            for cells in (batch, pairwise):
                np.testing.assert_allclose(row_key(*cells.robot(i)), row_key(A, b), atol=1e-7)


def test_the_builders_agree_in_3d_with_per_robot_radii():
    rng = np.random.default_rng(9)
    n = 30
    p = rng.uniform(-3, 3, (n, 3))
    radii = rng.uniform(0.05, 0.5, n)
    covs = np.array([np.diag(rng.uniform(0.0, 0.1, 3) ** 2) for _ in range(n)])
    geo = CellGeometry(ObstacleSet(np.zeros((0, 1, 3)), np.zeros((0, 3, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))),
                       *workspace_box_planes(np.full(3, -4.0), np.full(3, 4.0)))
    cells = build_cells(p, covs, radii, 1.6, geo, 2.0)
    for i in range(n):
        others = np.delete(np.arange(n), i)
        A, b, _ = cell_from_view(p[i], covs[i], radii[i], p[others], covs[others], 1.6, geo, 2.0, neighbour_radii=radii[others])
        np.testing.assert_allclose(row_key(*cells.robot(i)), row_key(A, b), atol=1e-7)


def test_each_robot_alone_gets_the_batch_velocity_with_per_robot_radii():
    rng = np.random.default_rng(5)
    n = 10
    radii = rng.uniform(0.05, 0.5, n)
    options = {"dt": 0.1, "v_max": 0.4, "bounds": (-4, -4, 4, 4), "obstacles": BOXES, "local_box": 2.0}
    p = place(rng, radii * 0.5, 3.5, BOXES)  # some pairs closer than r_i + r_j: estimates outside their cells too
    covs = np.array([random_covariance(rng, 0.0, 0.1) for _ in range(n)])
    desired = rng.uniform(-0.6, 0.6, (n, 2))
    batch = SafetyFilter.create(n, radius=radii, **options).filter(p, covs, desired)
    for i in range(n):
        others = np.delete(np.arange(n), i)
        robot = RobotSafetyFilter.create(radius=radii[i], deadlock=None, **options)
        mine = robot.filter(p[i], covs[i], desired[i], p[others], covs[others], neighbour_radii=radii[others])
        np.testing.assert_allclose(mine.velocity[0], batch.velocity[i], atol=1e-9)
        assert mine.estimate_in_cell[0] == batch.estimate_in_cell[i] and mine.empty[0] == batch.empty[i]
