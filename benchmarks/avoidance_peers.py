"""B-UAVC, robofleet's ORCA and RVO2's ORCA side by side on the same random cluttered scenes.

Three random scene generators (every scene a scenario mapping drawn from its seed; single
integrators, r_s = 0.2 m, v_max = 0.4 m/s, Δt = 0.1 s, the authors' δ = 0.1, σ = 0.1 m,
σ_o = 0.1 m; step budget by the shipped straight-line rule,
:func:`robofleet.avoidance.spec.straight_line_budget`):

* ``polygons`` — :func:`robofleet.avoidance.random_scenarios.random_scenario`: 8–16 robots
  in the authors' random antipodal swap among 2–6 random convex polygons;
* ``boxes`` — the same swap among 5–10 random boxes (sides 0.4–1.2 m, any yaw, at least
  0.9 m of free gap between any two);
* ``room`` — a walled 12 × 6 m room with a jittered grid of 0.3–0.6 m pillars (some left
  out), 8–16 robots from random free points of one end to random free points of the other
  (half of them each way).

Each scene runs with

* **B-UAVC**, the default (navigation rules on), on noisy estimates (σ, σ_o as above);
* **robofleet ORCA** (``method: orca``) on exact positions, the obstacles and walls as
  RVO2 handles them (:mod:`robofleet.avoidance.orca_obstacles`);
* **RVO2** (``pyrvo``, C++) on exact positions with the same polygons (solid polygons
  counter-clockwise, the bounds clockwise), the same parameters (10 neighbours within 3 m,
  τ = τ_o = 2 s) and the same rule as robofleet's ORCA loop: prefer the goal at
  ``min(v_max, d/Δt)`` until the robot is within the goal tolerance, then stand still;
* with ``--orca-noise``, robofleet ORCA also on the scene's noisy estimates.

Every method starts from the B-UAVC run's starts and goals (ORCA and RVO2 get them as an
explicit layout) and stops when every robot has arrived or the budget is spent.

Columns: **home** — scenes where every robot arrived (its controller's own estimate came
within the goal tolerance) and is home at the end (:data:`HOME_SIGMAS`: not away on a
yield, pushed off or holding short), with its Clopper–Pearson 95 % interval; **all arrived
once** — scenes where every robot arrived at some step (ORCA's and RVO2's arrived robots
stand still from then on and may be pushed off); **robots home** — share of robots home at
the end; **travel time** — mean arrival time of the robots,
over the scenes every method brought home (paired); **contacts** — robot–robot contact
pair-steps (centres closer than 2 r_s), robot–obstacle and robot–wall contact steps (centre
closer than r_s to a polygon or outside the walls shrunk by r_s), judged on TRUE positions
with :data:`CONTACT_TOL`, the scenes with any contact and the deepest overlap.

Run: ``python benchmarks/avoidance_peers.py [--scenes 20] [--first-seed 20000] [--generators polygons boxes room] [--orca-noise] [--jobs 1]``
(needs ``pip install 'robofleet[bench]'`` for ``pyrvo``; every run is seeded, ``--jobs``
does not change a figure).
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from _machine import machine
from avoidance_liveness import clopper_pearson

import robofleet
from robofleet.avoidance.orca import OrcaParams, preferred_velocities
from robofleet.avoidance.random_scenarios import random_scenario
from robofleet.avoidance.spec import TRAVEL_TIME_MULTIPLE
from robofleet.core import geometry
from robofleet.core.spec_blocks import ObstacleSpec

RADIUS, V_MAX, DT, TOLERANCE = 0.2, 0.4, 0.1, 0.1
ORCA = OrcaParams()
ROOM = (6.0, 3.0)


# ---------------------------------------------------------------------------------------
# the scene generators
# ---------------------------------------------------------------------------------------
def base_mapping(name: str, bounds, obstacles: list[dict], n: int, layout: dict, longest_trip: float) -> dict:
    steps = int(np.ceil(TRAVEL_TIME_MULTIPLE["single_integrator"] * longest_trip / V_MAX / DT - 1e-9))
    return {"family": "avoidance", "name": name, "method": "buavc", "delta": 0.1, "dt": DT, "max_steps": steps,
            "goal_tolerance": TOLERANCE, "local_box": 2.0, "record_cells": False,
            "workspace": {"bounds": bounds, "obstacle_sigma": 0.1, "obstacles": obstacles},
            "robots": {"n": n, "radius": RADIUS, "v_max": V_MAX, "sigma": 0.1, "layout": layout}}


def box_scene(seed: int) -> dict:
    """The authors' random antipodal swap among 5–10 random boxes."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(8, 17))
    boxes, placed = [], []
    for _ in range(int(rng.integers(5, 11))):
        for _ in range(200):
            c, size = rng.uniform(-3.8, 3.8, 2), rng.uniform(0.4, 1.2, 2)
            reach = 0.5 * float(np.hypot(*size))
            if all(np.linalg.norm(c - o) >= reach + r + 0.9 for o, r in placed):
                placed.append((c, reach))
                boxes.append({"center": np.round(c, 4).tolist(), "size": np.round(size, 4).tolist(), "yaw": round(float(rng.uniform(0, np.pi / 2)), 4)})
                break
    return base_mapping(f"boxes_{seed}", [-5, -5, 5, 5], boxes, n, {"kind": "antipodal", "r_min": 0.3, "r_max": 4.7}, 2 * 4.7)


def room_scene(seed: int) -> dict:
    """A walled room with a jittered grid of pillars; half the robots cross each way."""
    rng = np.random.default_rng(seed)
    hx, hy = ROOM
    pillars = []
    for x in np.linspace(-3.0, 3.0, 5):
        for y in np.linspace(-1.5, 1.5, 3):
            if rng.random() < 0.8:
                c, side = np.array([x, y]) + rng.uniform(-0.3, 0.3, 2), float(rng.uniform(0.3, 0.6))
                pillars.append({"center": np.round(c, 4).tolist(), "size": [round(side, 4)] * 2, "yaw": round(float(rng.uniform(0, np.pi / 2)), 4)})
    polygons = [ObstacleSpec(**p).polygon() for p in pillars]
    n = int(rng.integers(8, 17))
    left, right = free_points(rng, n, (-hx, -4.0), polygons), free_points(rng, n, (4.0, hx), polygons)
    half = n // 2
    starts = np.vstack([left[:half], right[half:]])
    goals = np.vstack([right[:half], left[half:]])
    layout = {"kind": "explicit", "starts": starts.round(4).tolist(), "goals": goals.round(4).tolist()}
    return base_mapping(f"room_{seed}", [-hx, -hy, hx, hy], pillars, n, layout, float(np.linalg.norm(starts - goals, axis=1).max()))


def free_points(rng, n: int, x_range: tuple[float, float], polygons: list[np.ndarray]) -> np.ndarray:
    """``n`` points in the strip ``x_range`` of the room, 0.8 m apart, 0.75 m from every
    pillar and 0.45 m from the walls (more than the clearances a B-UAVC start needs)."""
    hx, hy = ROOM
    out: list[np.ndarray] = []
    while len(out) < n:
        p = np.array([rng.uniform(*x_range), rng.uniform(-hy, hy)])
        if hx - abs(p[0]) < 0.45 or hy - abs(p[1]) < 0.45:
            continue
        if min(float(geometry.polygon_distance(p[None], q)[0]) for q in polygons) < 0.75:
            continue
        if all(np.linalg.norm(p - q) >= 0.8 for q in out):
            out.append(p)
    return np.array(out)


GENERATORS = {"polygons": random_scenario, "boxes": box_scene, "room": room_scene}


# ---------------------------------------------------------------------------------------
# the runs
# ---------------------------------------------------------------------------------------
HOME_SIGMAS = 4.0
"""A robot is home when its TRUE end position is within the goal tolerance + 4 σ of its goal:
robots stop on one noisy estimate within the tolerance (P(‖e‖ > 4σ) = e⁻⁸ per robot), and a
robot away on a yield (≥ 0.6 m) or holding short of its goal is not."""


CONTACT_TOL = 1e-6
"""Metres of overlap below which touching does not count as a contact here: RVO2 moves its
agents in single precision (an agent resting against an edge lands up to ~3·10⁻⁷ m inside
it), so the simulation's 10⁻⁷ would count rounding; every method is judged with this one."""


def judged(positions: np.ndarray, sigma: float, goals: np.ndarray, arrivals: np.ndarray, workspace) -> dict:
    """The figures of one run, the same way for every method (true positions ``(T + 1, N, 2)``,
    the position noise ``sigma`` the robots saw)."""
    pair_depth = np.array([2 * RADIUS - d for d in map(nearest_pair, positions)])
    obstacle_depth = RADIUS - workspace.obstacle_distance(positions) if workspace.obstacles else np.zeros(positions.shape[:2])
    wall_depth = RADIUS - workspace.boundary_distance(positions)
    at_goal = np.linalg.norm(positions[-1] - goals, axis=1) <= TOLERANCE + HOME_SIGMAS * sigma
    arrived = arrivals >= 0
    return {"home": bool(arrived.all() and at_goal.all()), "all_arrived": bool(arrived.all()), "robots_home": float(np.mean(at_goal & arrived)),
            "travel_time": float(np.mean(arrivals[arrived]) * DT) if arrived.any() else float("nan"),
            "pair_contacts": int(pair_contact_counts(positions).sum()),
            "obstacle_contacts": int(np.count_nonzero(obstacle_depth > CONTACT_TOL)), "wall_contacts": int(np.count_nonzero(wall_depth > CONTACT_TOL)),
            "deepest": float(max(pair_depth.max(initial=0.0), obstacle_depth.max(initial=0.0), wall_depth.max(initial=0.0), 0.0))}


def nearest_pair(points: np.ndarray) -> float:
    pairs = geometry.close_pairs(points, 2 * RADIUS)
    return float(np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1).min()) if len(pairs) else 2 * RADIUS


def pair_contact_counts(positions: np.ndarray) -> np.ndarray:
    """Robot pairs closer than ``2 r_s − CONTACT_TOL``, counted per step ``(T + 1,)``."""
    out = np.zeros(len(positions), int)
    for k, points in enumerate(positions):
        pairs = geometry.close_pairs(points, 2 * RADIUS - CONTACT_TOL)
        out[k] = len(pairs)
    return out


def buavc_run(mapping: dict, seed: int) -> tuple[dict, np.ndarray, np.ndarray]:
    spec = robofleet.load_scenario(mapping)
    trace = robofleet.simulate(spec, seed=seed)
    goals = np.asarray(trace.metadata["goals"])
    row = judged(trace.arrays["positions"], spec.robots.sigma, goals, trace.arrays["arrival_steps"], spec.workspace.build())
    return row, np.asarray(trace.metadata["starts"]), goals


def explicit(mapping: dict, starts: np.ndarray, goals: np.ndarray, noise: bool) -> dict:
    """``mapping`` for robofleet's ORCA from the given starts and goals (exact positions unless ``noise``)."""
    robots = {**mapping["robots"], "layout": {"kind": "explicit", "starts": starts.tolist(), "goals": goals.tolist()}}
    workspace = dict(mapping["workspace"])
    if not noise:
        robots["sigma"], workspace["obstacle_sigma"] = 0.0, 0.0
    return {**mapping, "method": "orca", "robots": robots, "workspace": workspace, "orca": ORCA.model_dump()}


def orca_run(mapping: dict, seed: int) -> dict:
    spec = robofleet.load_scenario(mapping)
    trace = robofleet.simulate(spec, seed=seed)
    return judged(trace.arrays["positions"], spec.robots.sigma, np.asarray(trace.metadata["goals"]),
                  trace.arrays["arrival_steps"], spec.workspace.build())


def rvo2_run(mapping: dict, starts: np.ndarray, goals: np.ndarray) -> dict:
    """RVO2 from the same starts with the same polygons and the same arrival rule."""
    import pyrvo

    workspace = robofleet.load_scenario(mapping).workspace.build()
    sim = pyrvo.RVOSimulator(DT, ORCA.neighbor_dist, ORCA.max_neighbors, ORCA.time_horizon, ORCA.time_horizon_obst, RADIUS, V_MAX)
    for polygon in workspace.obstacles:
        sim.add_obstacle([tuple(map(float, v)) for v in geometry.ensure_ccw(polygon)])
    sim.add_obstacle([tuple(map(float, v)) for v in geometry.ensure_ccw(workspace.bounds)[::-1]])
    sim.process_obstacles()
    for p in starts:
        sim.add_agent((float(p[0]), float(p[1])))
    n, positions = len(starts), [starts.copy()]
    arrivals = np.full(n, -1)
    for k in range(mapping["max_steps"]):  # as robofleet's loop: arrival seen at the step's start, stamped k + 1
        here = positions[-1]
        arrivals[(arrivals < 0) & (np.linalg.norm(here - goals, axis=1) <= TOLERANCE)] = k + 1
        arrived = arrivals >= 0
        pref = np.where(arrived[:, None], 0.0, preferred_velocities(here, goals, V_MAX, DT))
        for i, v in enumerate(pref):
            sim.set_agent_pref_velocity(i, (float(v[0]), float(v[1])))
        sim.do_step()
        positions.append(np.array([sim.get_agent_position(i).to_tuple() for i in range(n)]))
        if arrived.all():
            break
    track = np.array(positions)
    return judged(track, 0.0, goals, arrivals, workspace)


def scene_rows(job: tuple[str, int, bool]) -> dict:
    """Every method on one scene: ``{method: figures}``."""
    generator, seed, orca_noise = job
    mapping = GENERATORS[generator](seed)
    row, starts, goals = buavc_run(mapping, seed)
    out = {"B-UAVC": row, "robofleet ORCA": orca_run(explicit(mapping, starts, goals, False), seed), "RVO2": rvo2_run(mapping, starts, goals)}
    if orca_noise:
        out["robofleet ORCA, noisy estimates"] = orca_run(explicit(mapping, starts, goals, True), seed)
    return out


# ---------------------------------------------------------------------------------------
# the table
# ---------------------------------------------------------------------------------------
HEADER = ("| scenes | method | home [CP 95 %] | all arrived once | robots home | travel time, paired [s] | contacts robot–robot / –obstacle / –wall (steps) | scenes with a contact | deepest overlap [mm] |\n"
          "|---|---|---:|---:|---:|---:|---:|---:|---:|")


def table_rows(label: str, scenes: list[dict]) -> list[str]:
    methods = list(scenes[0])
    paired = [s for s in scenes if all(s[m]["home"] for m in methods)]
    rows = []
    for m in methods:
        runs = [s[m] for s in scenes]
        k, n = sum(r["home"] for r in runs), len(runs)
        lo, hi = clopper_pearson(k, n)
        travel = f"{np.mean([s[m]['travel_time'] for s in paired]):.1f} ({len(paired)})" if paired else "—"
        touched = sum(r["pair_contacts"] + r["obstacle_contacts"] + r["wall_contacts"] > 0 for r in runs)
        contacts = f"{sum(r['pair_contacts'] for r in runs)} / {sum(r['obstacle_contacts'] for r in runs)} / {sum(r['wall_contacts'] for r in runs)}"
        once = sum(r["all_arrived"] for r in runs)
        rows.append(f"| {label} | {m} | {k}/{n} = {100 * k / n:.0f} % [{100 * lo:.0f}, {100 * hi:.0f}] | {once}/{n} | "
                    f"{100 * np.mean([r['robots_home'] for r in runs]):.1f} % | {travel} | {contacts} | {touched} | "
                    f"{1e3 * max(r['deepest'] for r in runs):.3g} |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=20, help="scenes per generator")
    ap.add_argument("--first-seed", type=int, default=20000)
    ap.add_argument("--generators", nargs="+", choices=list(GENERATORS), default=list(GENERATORS))
    ap.add_argument("--orca-noise", action="store_true", help="also robofleet's ORCA on the scene's noisy estimates")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (results do not depend on it)")
    args = ap.parse_args()
    print(machine())
    print(HEADER)
    t0 = time.perf_counter()
    seeds = range(args.first_seed, args.first_seed + args.scenes)
    every: list[dict] = []
    for generator in args.generators:
        jobs = [(generator, s, args.orca_noise) for s in seeds]
        if args.jobs > 1:
            with ProcessPoolExecutor(args.jobs) as pool:
                scenes = list(pool.map(scene_rows, jobs))
        else:
            scenes = [scene_rows(j) for j in jobs]
        every += scenes
        print("\n".join(table_rows(f"{generator} {seeds.start}–{seeds.stop - 1}", scenes)), flush=True)
    if len(args.generators) > 1:
        print("\n".join(table_rows("all", every)))
    print(f"wall time: {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
