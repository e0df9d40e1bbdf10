"""Random 2-D B-UAVC scenes for liveness benchmarks and tests: three generators by name.

Each scene is a plain scenario MAPPING (what :func:`robofleet.load_scenario` takes) drawn
from a seed: single integrators, r_s = 0.2 m, v_max = 0.4 m/s, Δt = 0.1 s, the authors'
δ = 0.1, σ = 0.1 m, σ_o = 0.1 m, goal tolerance 0.1 m, step budget by the shipped
straight-line rule (:func:`.spec.straight_line_budget`). Pure: no file I/O, the same seed
gives the same mapping.

* ``polygons`` (:func:`random_scenario`) — 8–16 robots in the authors' random antipodal
  swap (docs/theory/buavc.md "Setups": robot i at a random angle in its own sector, radius
  U(0.3, 4.7) m, goal = −start; the swap itself is drawn by the run's own seed) among 2–6
  random convex obstacles (3–6 vertices, 0.3–0.7 m across, kept away from the centre);
* ``boxes`` (:func:`box_scene`) — the same swap among 5–10 random boxes (sides 0.4–1.2 m,
  any yaw, at least 0.9 m of free gap between any two);
* ``room`` (:func:`room_scene`) — a walled 12 × 6 m room with a jittered 5 × 3 grid of
  0.3–0.6 m pillars (each kept with probability 0.8), robots from random free points of
  one end to random free points of the other, half of them each way.

:data:`GENERATORS` maps each name to its function; :func:`scene` draws by name.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..core import geometry
from ..core.errors import ConfigError, short_repr
from ..core.spec_blocks import ObstacleSpec
from .spec import TRAVEL_TIME_MULTIPLE

ROBOTS = (8, 16)
OBSTACLES = (2, 6)
BOUND = 5.0
R_MAX = 4.7
RADIUS, V_MAX, DT, TOLERANCE = 0.2, 0.4, 0.1, 0.1
ROOM = (6.0, 3.0)
"""Half extents of the ``room`` generator's walls [m]."""

END_STRIP = 4.0
"""``room`` robots start and end at ``|x| ≥ END_STRIP`` (the two ends of the room)."""

PLACEMENT_DRAWS = 100_000
"""Candidate points :func:`free_points` draws for one end of the room before it stops: random
sequential placement can jam (no free point 0.8 m from every placed one is left), and the
end then holds fewer robots than drawn."""


# ---------------------------------------------------------------------------------------
# polygons
# ---------------------------------------------------------------------------------------
def random_convex_polygon(rng: np.random.Generator, center: np.ndarray, radius: float) -> list[list[float]]:
    """A convex polygon: 3–6 points at sorted random angles on a circle of ``radius``."""
    k = int(rng.integers(3, 7))
    angles = np.sort(rng.uniform(0.0, 2 * np.pi, k))
    angles = angles[np.concatenate([[True], np.diff(angles) > 0.3])]
    if len(angles) < 3:
        angles = np.array([0.0, 2.1, 4.2]) + angles[0]
    pts = center + radius * np.column_stack([np.cos(angles), np.sin(angles)])
    return np.round(pts, 4).tolist()


def random_obstacles(rng: np.random.Generator, count: int) -> list[dict]:
    """``count`` non-overlapping convex obstacles with centres in ``[-3.5, 3.5]²``."""
    centers: list[np.ndarray] = []
    out = []
    while len(out) < count:
        c, r = rng.uniform(-3.5, 3.5, 2), float(rng.uniform(0.3, 0.7))
        if any(np.linalg.norm(c - o) < r + 1.6 for o in centers):
            continue
        centers.append(c)
        out.append({"vertices": random_convex_polygon(rng, c, r)})
    return out


def budget(longest_trip: float) -> int:
    """The shipped straight-line step budget of a single integrator for ``longest_trip`` metres."""
    return int(np.ceil(TRAVEL_TIME_MULTIPLE["single_integrator"] * longest_trip / V_MAX / DT - 1e-9))


def random_scenario(seed: int) -> dict:
    """The ``polygons`` scene of ``seed``."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(ROBOTS[0], ROBOTS[1] + 1))
    obstacles = random_obstacles(rng, int(rng.integers(OBSTACLES[0], OBSTACLES[1] + 1)))
    return {
        "family": "avoidance", "name": f"random_{seed}", "method": "buavc", "delta": 0.1, "dt": DT,
        "max_steps": budget(2 * R_MAX), "goal_tolerance": TOLERANCE, "local_box": 2.0,
        "workspace": {"bounds": [-BOUND, -BOUND, BOUND, BOUND], "obstacle_sigma": 0.1, "obstacles": obstacles},
        "robots": {"n": n, "radius": RADIUS, "v_max": V_MAX, "sigma": 0.1, "layout": {"kind": "antipodal", "r_min": 0.3, "r_max": R_MAX}},
    }


# ---------------------------------------------------------------------------------------
# boxes and room
# ---------------------------------------------------------------------------------------
def base_mapping(name: str, bounds, obstacles: list[dict], n: int, layout: dict, longest_trip: float) -> dict:
    """A ``boxes``/``room`` scene mapping (cells not recorded)."""
    return {"family": "avoidance", "name": name, "method": "buavc", "delta": 0.1, "dt": DT, "max_steps": budget(longest_trip),
            "goal_tolerance": TOLERANCE, "local_box": 2.0, "record_cells": False,
            "workspace": {"bounds": bounds, "obstacle_sigma": 0.1, "obstacles": obstacles},
            "robots": {"n": n, "radius": RADIUS, "v_max": V_MAX, "sigma": 0.1, "layout": layout}}


def box_scene(seed: int) -> dict:
    """The ``boxes`` scene of ``seed``: the authors' random antipodal swap among 5–10 random boxes."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(ROBOTS[0], ROBOTS[1] + 1))
    boxes, placed = [], []
    for _ in range(int(rng.integers(5, 11))):
        for _ in range(200):
            c, size = rng.uniform(-3.8, 3.8, 2), rng.uniform(0.4, 1.2, 2)
            reach = 0.5 * float(np.hypot(*size))
            if all(np.linalg.norm(c - o) >= reach + r + 0.9 for o, r in placed):
                placed.append((c, reach))
                boxes.append({"center": np.round(c, 4).tolist(), "size": np.round(size, 4).tolist(), "yaw": round(float(rng.uniform(0, np.pi / 2)), 4)})
                break
    return base_mapping(f"boxes_{seed}", [-BOUND, -BOUND, BOUND, BOUND], boxes, n, {"kind": "antipodal", "r_min": 0.3, "r_max": R_MAX}, 2 * R_MAX)


def room_scene(seed: int) -> dict:
    """The ``room`` scene of ``seed``: a walled room with a jittered grid of pillars; half
    the robots cross each way (fewer than drawn when an end jams, :data:`PLACEMENT_DRAWS`)."""
    rng = np.random.default_rng(seed)
    hx, hy = ROOM
    pillars = []
    for x in np.linspace(-3.0, 3.0, 5):
        for y in np.linspace(-1.5, 1.5, 3):
            if rng.random() < 0.8:
                c, side = np.array([x, y]) + rng.uniform(-0.3, 0.3, 2), float(rng.uniform(0.3, 0.6))
                pillars.append({"center": np.round(c, 4).tolist(), "size": [round(side, 4)] * 2, "yaw": round(float(rng.uniform(0, np.pi / 2)), 4)})
    polygons = [ObstacleSpec(**p).polygon() for p in pillars]
    n = int(rng.integers(ROBOTS[0], ROBOTS[1] + 1))
    left = free_points(rng, n, (-hx, -END_STRIP), polygons)
    right = free_points(rng, n, (END_STRIP, hx), polygons)
    n = min(len(left), len(right))
    half = n // 2
    starts = np.vstack([left[:half], right[half:n]])
    goals = np.vstack([right[:half], left[half:n]])
    layout = {"kind": "explicit", "starts": starts.round(4).tolist(), "goals": goals.round(4).tolist()}
    return base_mapping(f"room_{seed}", [-hx, -hy, hx, hy], pillars, n, layout, float(np.linalg.norm(starts - goals, axis=1).max()))


def free_points(rng: np.random.Generator, n: int, x_range: tuple[float, float], polygons: list[np.ndarray]) -> np.ndarray:
    """Up to ``n`` points ``(m, 2)`` in the strip ``x_range`` of the room by random sequential
    placement: 0.8 m apart, 0.75 m from every pillar and 0.45 m from the walls (more than the
    clearances a B-UAVC start needs). Stops after :data:`PLACEMENT_DRAWS` candidates."""
    hx, hy = ROOM
    out = np.empty((0, 2))
    for _ in range(PLACEMENT_DRAWS):
        p = np.array([rng.uniform(*x_range), rng.uniform(-hy, hy)])
        if hx - abs(p[0]) < 0.45 or hy - abs(p[1]) < 0.45:
            continue
        if len(out) and np.sqrt(((out - p) ** 2).sum(axis=1)).min() < 0.8:
            continue
        if min(float(geometry.polygon_distance(p[None], q)[0]) for q in polygons) < 0.75:
            continue
        out = np.vstack([out, p])
        if len(out) == n:
            break
    return out


GENERATORS: dict[str, Callable[[int], dict]] = {"polygons": random_scenario, "boxes": box_scene, "room": room_scene}
"""The random scene generators by name."""


def scene(generator: str, seed: int) -> dict:
    """The scene of ``seed`` from the generator named ``generator`` (a key of :data:`GENERATORS`)."""
    if generator not in GENERATORS:
        raise ConfigError(f"generator: expected one of {', '.join(GENERATORS)}, received {short_repr(generator)}")
    return GENERATORS[generator](seed)
