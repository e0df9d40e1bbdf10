"""Adversarial search for the braking rule's guarantee (braking.py): with exact estimates a
double integrator never leaves its cell and no robot touches another or an obstacle.

Random cluttered arenas, zero noise, mixed teams of single and double integrators (the
two models whose controllers keep their cells; random ``v_max``, ``a_max``, ``dt`` and
radius per world), random goal sequences (a robot that arrives, and now and then any
robot, gets a new random goal), liveness rules off, on, and on with the roadmap. Every
step checks, for every robot, that the motion within the step (sampled) and a double
integrator's next braking segment lie in the cell it was given, and that no two robots
and no robot and obstacle come closer than their radii at the sampled instants. Many
walled arenas share one world (robots of different arenas are farther apart than the
local box, so they never see each other): an episode is an arena.
"""

from dataclasses import dataclass

import numpy as np
import pytest

import robofleet
from robofleet.avoidance.braking import stopping_distance, stopping_point
from robofleet.avoidance.metrics import box_distance
from robofleet.avoidance.random_scenarios import random_convex_polygon
from robofleet.avoidance.simulation import World
from robofleet.avoidance.spec import team_points
from robofleet.core.metrics import CONTACT_TOL
from robofleet.dynamics.double_integrator import saturate_norm

TAU = np.linspace(0.0, 1.0, 5)[1:]  # instants sampled within each step (fractions of Δt)
CELL_TOL = 1e-8  # the rule accepts points 1e-9 outside a row (rounding); contacts: CONTACT_TOL
WALL = 0.1  # thickness of an arena's walls [m]
HALF = (1.2, 2.0)  # half-width of an arena [m]
FAR_POLYGON = np.array([[1e6, 1e6], [1e6 + 1, 1e6], [1e6, 1e6 + 1]])


@dataclass
class Arenas:
    """A world of arenas: its spec, each robot's arena, each arena's centre, half-width
    and padded obstacles (walls included) ``(A, O, V, 2)``."""

    spec: object
    arena_of: np.ndarray
    centers: np.ndarray
    halves: np.ndarray
    obstacles: np.ndarray


def random_teams(rng):
    """A random Δt, one double-integrator team and up to two more of either model, and the
    largest reach ``v_max Δt + D(v_max)`` (``v_max Δt`` for a single integrator): the
    local box is set from it to keep the guarantee's premise (braking.py)."""
    dt = float(rng.choice([0.05, 0.1, 0.2]))
    kinds = ["double_integrator"] + list(rng.choice(["single_integrator", "double_integrator"], int(rng.integers(0, 3))))
    teams, reach = [], []
    for k, kind in enumerate(kinds):
        v_max = float(rng.uniform(0.3, 1.2))
        model = {"kind": str(kind)}
        if kind == "double_integrator":
            model["a_max"] = float(np.exp(rng.uniform(np.log(0.3), np.log(4.0))))
            reach.append(v_max * dt + float(stopping_distance(v_max, model["a_max"], dt)))
        else:
            reach.append(v_max * dt)
        teams.append({"name": f"t{k}", "model": model, "v_max": v_max, "sigma": 0.0})
    return dt, teams, max(reach)


def free_points(rng, count, center, half, polygons, radius, apart=True):
    """Up to ``count`` random points of the arena at least ``radius`` (+ 2 cm) from its
    walls and obstacles ``(O, V, 2)`` and, if ``apart``, ``2 radius`` (+ 2 cm) from each other."""
    margin = radius + 0.02
    candidates = center + rng.uniform(-half + margin, half - margin, (50 * count, 2))
    free = candidates[EdgeSet(polygons[None]).distance(candidates[None])[0] >= margin]
    out = []
    for p in free:
        if len(out) == count:
            break
        if not apart or all(np.linalg.norm(p - q) >= 2 * margin for q in out):
            out.append(p)
    return out


def arena_polygons(rng, center, half, walls):
    """Up to 3 random convex obstacles in the arena (and its 4 walls when ``walls``), padded ``(O, V, 2)``."""
    polygons, placed = [], []
    for _ in range(int(rng.integers(1, 4))):
        for _ in range(30):
            c, r = center + rng.uniform(-half + 0.6, half - 0.6, 2), float(rng.uniform(0.2, 0.5))
            if all(np.linalg.norm(c - o) >= r + ro + 0.4 for o, ro in placed):
                placed.append((c, r))
                polygons.append(np.array(random_convex_polygon(rng, c, r)))
                break
    if walls:
        lo, hi = center - half, center + half
        polygons += [np.array([[lo[0] - WALL, lo[1] - WALL], [hi[0] + WALL, lo[1] - WALL], [hi[0] + WALL, lo[1]], [lo[0] - WALL, lo[1]]]),
                     np.array([[lo[0] - WALL, hi[1]], [hi[0] + WALL, hi[1]], [hi[0] + WALL, hi[1] + WALL], [lo[0] - WALL, hi[1] + WALL]]),
                     np.array([[lo[0] - WALL, lo[1]], [lo[0], lo[1]], [lo[0], hi[1]], [lo[0] - WALL, hi[1]]]),
                     np.array([[hi[0], lo[1]], [hi[0] + WALL, lo[1]], [hi[0] + WALL, hi[1]], [hi[0], hi[1]]])]
    return polygons


def pad_polygons(polygons, count, width=6):
    """Polygons ``(count, width, 2)``, vertices padded by repetition, missing ones far away."""
    out = np.repeat(np.vstack([FAR_POLYGON, np.repeat(FAR_POLYGON[-1:], width - 3, 0)])[None], count, 0)
    for k, p in enumerate(polygons):
        out[k] = np.vstack([p, np.repeat(p[-1:], width - len(p), 0)])
    return out


def arenas_world(seed, count, roadmap):
    """A world of ``count`` arenas (``roadmap``: one arena bounded by the workspace itself,
    liveness with the roadmap; else walled arenas, liveness off or on without it)."""
    rng = np.random.default_rng(seed)
    dt, teams, reach = random_teams(rng)
    radius = float(rng.uniform(0.1, 0.25))
    local_box = max(1.0, 2.0 * (radius + reach) + 0.05)
    spacing = 2.0 * (HALF[1] + WALL) + local_box + 0.5
    side = int(np.ceil(np.sqrt(count)))
    centers = spacing * np.array([[k % side, k // side] for k in range(count)], dtype=float)
    halves = rng.uniform(*HALF, count)
    members = [[] for _ in teams]  # (start, goal) per team
    all_polygons, arena_of_member = [], [[] for _ in teams]
    for k in range(count):
        polygons = arena_polygons(rng, centers[k], halves[k], walls=not roadmap)
        all_polygons.append(polygons)
        padded = pad_polygons(polygons, len(polygons))
        n = int(rng.integers(2, 7))
        starts = free_points(rng, n, centers[k], halves[k], padded, radius)
        goals = free_points(rng, len(starts), centers[k], halves[k], padded, radius)
        for s, g in zip(starts, goals):
            t = int(rng.integers(len(teams)))
            members[t].append((s, g))
            arena_of_member[t].append(k)
    teams = [dict(t, n=len(m), layout={"kind": "explicit", "starts": [list(s) for s, _ in m], "goals": [list(g) for _, g in m]})
             for t, m in zip(teams, members) if m]
    arena_of = np.concatenate([a for a in arena_of_member if a])
    lo, hi = centers.min(0) - HALF[1] - 1.0, centers.max(0) + HALF[1] + 1.0
    if roadmap:
        lo, hi = centers[0] - halves[0], centers[0] + halves[0]
    navigation = {"enabled": True, "route": {"enabled": True}} if roadmap else {"enabled": bool(rng.integers(2)), "route": {"enabled": False}}
    spec = robofleet.load_scenario({
        "family": "avoidance", "name": f"braking_adversary_{seed}", "method": str(rng.choice(["buavc", "bvc"])), "dt": dt,
        "max_steps": 1000, "goal_tolerance": 0.1, "local_box": local_box, "navigation": navigation,
        "workspace": {"bounds": [*map(float, lo), *map(float, hi)], "obstacle_sigma": 0.0,
                      "obstacles": [{"vertices": p.tolist()} for ps in all_polygons for p in ps]},
        "robots": {"radius": radius, "sigma": 0.0}, "teams": teams,
    })
    most = max(len(ps) for ps in all_polygons)
    obstacles = np.stack([pad_polygons(ps, most) for ps in all_polygons])
    return Arenas(spec, arena_of, centers, halves, obstacles), rng


class EdgeSet:
    """The edges of each robot's convex counter-clockwise polygons ``(N, O, V, 2)``, for
    the distance from points to the nearest polygon (0 inside)."""

    def __init__(self, polygons):
        start = polygons[:, None]  # (N, 1, O, V, 2)
        edge = np.roll(polygons, -1, axis=2)[:, None] - start
        self.sx, self.sy, self.ex, self.ey = start[..., 0], start[..., 1], edge[..., 0], edge[..., 1]  # (N, 1, O, V) each
        self.len2 = self.ex * self.ex + self.ey * self.ey
        self.safe_len2 = np.where(self.len2 > 0, self.len2, 1.0)

    def distance(self, points):
        """``(N, S)`` for points ``(N, S, 2)`` (coordinates apart: no reduction over a
        last axis of two)."""
        rx = points[:, :, None, None, 0] - self.sx  # (N, S, O, V)
        ry = points[:, :, None, None, 1] - self.sy
        t = np.clip((rx * self.ex + ry * self.ey) / self.safe_len2, 0.0, 1.0)
        dx, dy = t * self.ex - rx, t * self.ey - ry
        dist = np.sqrt(np.min(dx * dx + dy * dy, -1))  # (N, S, O)
        inside = np.all((self.ex * ry - self.ey * rx >= 0) | (self.len2 == 0), axis=-1)
        return np.where(inside, 0.0, dist).min(-1)


def inside_cells(A, b, valid, points, tol=CELL_TOL):
    """``(N,)``: all of each robot's points ``(N, K, 2)`` lie in its cell."""
    slack = np.einsum("nmd,nkd->nkm", A, points) - b[:, None, :]
    return np.all((slack <= tol) | ~valid[:, None, :], axis=(1, 2))


def motion_samples(world, u):
    """Each robot's positions within the coming step ``(N, S, 2)`` and the points that must
    lie in its cell ``(N, S + 1, 2)`` (a double integrator's: also its next stopping point)."""
    dt = world.dt
    path = np.empty((world.n, len(TAU), 2))
    keep = np.empty((world.n, len(TAU) + 1, 2))
    for g in world.groups:
        p = g.state[:, :2]
        t = TAU[None, :, None] * dt
        if g.kind == "double_integrator":
            v, a = g.state[:, 2:], saturate_norm(u[g.index, :2], g.params.a_max)
            path[g.index] = p[:, None] + v[:, None] * t + 0.5 * a[:, None] * t * t
            keep[g.index, -1] = stopping_point(path[g.index, -1], v + a * dt, g.params.a_max, dt)
        else:
            path[g.index] = p[:, None] + u[g.index, None, :2] * t
            keep[g.index, -1] = path[g.index, -1]
        keep[g.index, :-1] = path[g.index]
    return path, keep


def new_goals(world, which, draw):
    """New goals ``draw(i)`` (a point, or ``None`` to keep the goal) for robots ``which``:
    their arrival unlatched, their team's roadmap re-planned."""
    for i in which:
        point = draw(i)
        if point is not None:
            world.goals[i, :2] = point
    world.retarget(np.asarray(which))


def run_world(seed, count, steps, roadmap=False):
    """The search on one world: ``(arenas with a failure, steps out of cell, contacts,
    smallest clearance [m], moving double-integrator robot-steps)``."""
    arenas, rng = arenas_world(seed, count, roadmap)
    world = World(arenas.spec, np.random.default_rng(seed))
    radius = arenas.spec.robots.radius
    shift = np.zeros((world.n_obstacles, 2))
    bad = np.zeros(count, bool)
    out_of_cell = contacts = moving = 0
    clearance = np.inf
    first, second = np.nonzero(np.triu(arenas.arena_of[:, None] == arenas.arena_of[None], 1))  # pairs of one arena
    edges = EdgeSet(arenas.obstacles[arenas.arena_of])

    def draw(i):  # a random free goal in robot i's arena
        k = arenas.arena_of[i]
        point = free_points(rng, 1, arenas.centers[k], arenas.halves[k], arenas.obstacles[k], radius, apart=False)
        return point[0] if point else None

    for _ in range(steps):
        positions = world.positions()
        cells, u, _ = world.decide(positions, shift)  # exact estimates
        path, keep = motion_samples(world, u)
        left = ~inside_cells(cells.A, cells.b, cells.valid, keep)
        gaps = np.linalg.norm(path[first] - path[second], axis=-1).min(-1) - 2 * radius  # (pairs,)
        inside = arenas.halves[arenas.arena_of, None] - np.abs(path - arenas.centers[arenas.arena_of, None]).max(-1)
        obstacle_gaps = np.minimum(edges.distance(path), inside).min(-1) - radius  # (N,): obstacles, walls, bounds
        touch = np.zeros(world.n, bool)
        touch[first[gaps < -CONTACT_TOL]] = touch[second[gaps < -CONTACT_TOL]] = True
        touch |= obstacle_gaps < -CONTACT_TOL
        out_of_cell += int(left.sum())
        contacts += int(np.count_nonzero(gaps < -CONTACT_TOL)) + int(np.count_nonzero(obstacle_gaps < -CONTACT_TOL))
        clearance = min(clearance, float(gaps.min(initial=np.inf)), float(obstacle_gaps.min()))
        bad[arenas.arena_of[left | touch]] = True
        moving += sum(int(np.count_nonzero(np.any(g.state[:, 2:] != 0, axis=1))) for g in world.groups if g.kind == "double_integrator")
        world.advance(u)
        new_goals(world, np.flatnonzero(world.arrived() | (rng.random(world.n) < 0.02)), draw)
    return int(bad.sum()), out_of_cell, contacts, clearance, moving


def search(seeds, count, steps, roadmap=False):
    """The search over worlds ``seeds``: totals of :func:`run_world` and the episodes."""
    totals = np.zeros(3, np.int64)
    clearance, moving = np.inf, 0
    for seed in seeds:
        bad, out_of_cell, contacts, gap, moved = run_world(seed, count, steps, roadmap)
        totals += (bad, out_of_cell, contacts)
        clearance, moving = min(clearance, gap), moving + moved
    return {"episodes": len(seeds) * count, "failed_episodes": int(totals[0]), "steps_out_of_cell": int(totals[1]),
            "contacts": int(totals[2]), "min_clearance": clearance, "moving_double_integrator_steps": moving}


def boxes_world(seed):
    """One 3-D space with yawed boxes (some on the floor, some hovering within reach of the
    ground robots) and ground teams of both models."""
    rng = np.random.default_rng(seed)
    dt, teams, reach = random_teams(rng)
    radius = float(rng.uniform(0.1, 0.25))
    half = float(rng.uniform(*HALF)) + 0.5
    boxes = []
    for _ in range(int(rng.integers(1, 4))):
        size = [float(rng.uniform(0.3, 0.8)), float(rng.uniform(0.3, 0.8)), float(rng.uniform(0.5, 2.0))]
        bottom = 0.0 if rng.random() < 0.6 else float(rng.uniform(0.5, 1.8)) * radius
        center = [*map(float, rng.uniform(-half + 0.6, half - 0.6, 2)), bottom + 0.5 * size[2]]
        boxes.append({"center": center, "size": size, "yaw": float(rng.uniform(0, np.pi))})
    centers, sizes, yaws = (np.array([b[k] for b in boxes], float) for k in ("center", "size", "yaw"))

    def free(count, apart=True):
        cand = rng.uniform(-half + radius + 0.02, half - radius - 0.02, (50 * count, 2))
        ok = box_distance(np.column_stack([cand, np.full(len(cand), radius)]), centers, sizes, yaws).min(-1) >= radius + 0.02
        out = []
        for p in cand[ok]:
            if len(out) < count and (not apart or all(np.linalg.norm(p - q) >= 2 * radius + 0.04 for q in out)):
                out.append(p)
        return out

    for _ in range(100):  # circle layouts (explicit ground starts in 3-D are not accepted), redrawn until valid
        listed = [dict(t, n=int(rng.integers(1, 4)), layout={"kind": "circle", "radius": float(rng.uniform(0.4, half - radius - 0.1)),
                                                              "center": [0.0, 0.0], "phase": float(rng.uniform(0, 2 * np.pi))})
                  for t in teams]
        try:
            spec = robofleet.load_scenario({
                "family": "avoidance", "name": f"braking_adversary_3d_{seed}", "method": "buavc", "dt": dt, "max_steps": 1000,
                "goal_tolerance": 0.1, "local_box": max(1.0, 2.0 * (radius + reach) + 0.05),
                "navigation": {"enabled": bool(rng.integers(2))},
                "space3d": {"bounds": [-half, -half, 0.0, half, half, 2.5], "boxes": boxes, "obstacle_sigma": 0.0},
                "robots": {"radius": radius, "sigma": 0.0}, "teams": listed,
            })
        except robofleet.ScenarioError:
            continue
        ends = np.concatenate([np.concatenate(team_points(t, 3, spec.ground_height())) for t in spec.team_specs()])
        if box_distance(ends, centers, sizes, yaws).min() >= radius + 0.02:
            break
    return spec, rng, free, (centers, sizes, yaws), half


def run_boxes_world(seed, steps):
    """The search on one 3-D world (as :func:`run_world`, one episode)."""
    spec, rng, free, boxes, half = boxes_world(seed)
    world = World(spec, np.random.default_rng(seed))
    radius, z = spec.robots.radius, spec.ground_height()
    shift = np.zeros((world.n_obstacles, 3))
    first, second = np.triu_indices(world.n, 1)
    out_of_cell = contacts = moving = 0
    clearance = np.inf
    for _ in range(steps):
        cells, u, _ = world.decide(world.positions(), shift)
        path, keep = motion_samples(world, u)
        for g in world.groups:
            rows = world.team_cells(cells, g)
            out_of_cell += int(np.count_nonzero(~inside_cells(rows.A, rows.b, rows.valid, keep[g.index])))
        gaps = np.linalg.norm(path[first] - path[second], axis=-1).min(-1) - 2 * radius
        to_boxes = box_distance(np.concatenate([path, np.full(path.shape[:2] + (1,), z)], -1), *boxes).min(-1)
        obstacle_gaps = np.minimum(to_boxes, half - np.abs(path).max(-1)).min(-1) - radius  # (N,): boxes and bounds
        contacts += int(np.count_nonzero(gaps < -CONTACT_TOL)) + int(np.count_nonzero(obstacle_gaps < -CONTACT_TOL))
        clearance = min(clearance, float(gaps.min(initial=np.inf)), float(obstacle_gaps.min()))
        moving += sum(int(np.count_nonzero(np.any(g.state[:, 2:] != 0, axis=1))) for g in world.groups if g.kind == "double_integrator")
        world.advance(u)
        new_goals(world, np.flatnonzero(world.arrived() | (rng.random(world.n) < 0.02)), lambda i: next(iter(free(1, apart=False)), None))
    return {"episodes": 1, "failed_episodes": int(out_of_cell + contacts > 0), "steps_out_of_cell": out_of_cell, "contacts": contacts,
            "min_clearance": clearance, "moving_double_integrator_steps": moving}


def assert_safe(result):
    assert result["steps_out_of_cell"] == 0 and result["contacts"] == 0, result
    assert result["min_clearance"] >= -CONTACT_TOL, result
    assert result["moving_double_integrator_steps"] > 0


def test_double_integrators_keep_their_cells_across_cell_changes():
    """A few hundred arenas: no robot leaves its cell, no contact (fails without the braking
    segments in the cells: the cells move between steps and the braking segment of a
    double integrator pokes out of its next cell)."""
    assert_safe(search(range(6), 40, 50))


def test_double_integrators_keep_their_cells_with_the_roadmap():
    """Single arenas with the roadmap (and goals re-planned on every change)."""
    assert_safe(search(range(100, 110), 1, 60, roadmap=True))


def test_ground_double_integrators_keep_their_cells_among_3d_boxes():
    """Ground teams in 3-D spaces: the braking segments against yawed boxes (golden-section
    segment–box planes) and against each other."""
    for seed in range(8):
        assert_safe(run_boxes_world(seed, 40))


FULL_SEARCH = {  # the full search, in parts that the workers of `pytest -n 2` share
    "arenas 1000-1019": lambda: search(range(1000, 1020), 50, 50),
    "arenas 1020-1039": lambda: search(range(1020, 1040), 50, 50),
    "roadmap 2000-2039": lambda: search(range(2000, 2040), 1, 60, roadmap=True),
}


@pytest.mark.slow
@pytest.mark.parametrize("part", FULL_SEARCH)
def test_braking_adversarial_search_thousands_of_episodes(part):
    """The full search: thousands of arenas (navigation off and on, any ``a_max``); its 3-D
    part is the next test (together about 50 s on one core)."""
    assert_safe(FULL_SEARCH[part]())


@pytest.mark.slow
@pytest.mark.parametrize("seeds", [range(3000, 3020), range(3020, 3040)], ids=["boxes 3000-3019", "boxes 3020-3039"])
def test_braking_adversarial_search_among_3d_boxes(seeds):
    """The full search's 3-D spaces with boxes."""
    for seed in seeds:
        assert_safe(run_boxes_world(seed, 40))
