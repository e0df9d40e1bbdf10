"""Random 2-D B-UAVC scenarios for liveness benchmarks.

Each scenario is a plain scenario MAPPING (what :func:`robofleet.load_scenario` takes)
drawn from a seed (step budget by the shipped rule, :func:`.spec.straight_line_budget`): 8–16 single-integrator robots in the authors' random antipodal swap
(docs/theory/buavc.md "Setups": robot i at a random angle in its own sector, radius
U(0.3, 4.7) m, goal = −start; the swap itself is drawn by the run's own seed) among
2–6 random convex obstacles (random convex polygons of 3–6 vertices, 0.3–0.7 m across,
kept away from the centre ring nothing is guaranteed about). Pure: no file I/O, the
same seed gives the same mapping.
"""

from __future__ import annotations

import numpy as np

from .spec import TRAVEL_TIME_MULTIPLE

ROBOTS = (8, 16)
OBSTACLES = (2, 6)
BOUND = 5.0
R_MAX = 4.7


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


def random_scenario(seed: int) -> dict:
    """The scenario mapping of ``seed`` (single integrators, B-UAVC, the authors' δ, Σ, r_s)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(ROBOTS[0], ROBOTS[1] + 1))
    obstacles = random_obstacles(rng, int(rng.integers(OBSTACLES[0], OBSTACLES[1] + 1)))
    v_max = 0.4
    steps = int(np.ceil(TRAVEL_TIME_MULTIPLE["single_integrator"] * 2 * R_MAX / v_max / 0.1 - 1e-9))  # the shipped rule
    return {
        "family": "avoidance", "name": f"random_{seed}", "method": "buavc", "delta": 0.1, "dt": 0.1,
        "max_steps": steps, "goal_tolerance": 0.1, "local_box": 2.0,
        "workspace": {"bounds": [-BOUND, -BOUND, BOUND, BOUND], "obstacle_sigma": 0.1, "obstacles": obstacles},
        "robots": {"n": n, "radius": 0.2, "v_max": v_max, "sigma": 0.1, "layout": {"kind": "antipodal", "r_min": 0.3, "r_max": R_MAX}},
    }
