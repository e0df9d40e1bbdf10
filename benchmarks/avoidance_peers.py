"""B-UAVC, robofleet's ORCA and RVO2's ORCA side by side on the same random cluttered scenes.

The three random scene generators of :mod:`robofleet.avoidance.random_scenarios`
(``polygons``, ``boxes``, ``room``; every scene a scenario mapping drawn from its seed,
single integrators, the authors' δ, σ, σ_o, step budget by the shipped straight-line rule).

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
with :data:`CONTACT_TOL`, the scenes with any contact and the deepest overlap; **CPU per
scene** — process CPU time of one method's run (loading and simulating), mean and largest.
Below each generator's rows: the seeds where B-UAVC did not bring every robot home, and
the scenes left out because the antipodal sampler found no start for some robot (a crowded
sector among the boxes; the layout is drawn by the run's seed, so every method skips them).

Run: ``python benchmarks/avoidance_peers.py [--scenes 20] [--first-seed 20000] [--generators polygons boxes room] [--buavc-only] [--orca-noise] [--jobs 1]``
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
from robofleet.avoidance.random_scenarios import DT, GENERATORS, RADIUS, TOLERANCE, V_MAX
from robofleet.core import geometry
from robofleet.core.errors import ScenarioError

ORCA = OrcaParams()


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
    cpu = time.process_time()
    spec = robofleet.load_scenario(mapping)
    trace = robofleet.simulate(spec, seed=seed)
    cpu = time.process_time() - cpu
    goals = np.asarray(trace.metadata["goals"])
    row = judged(trace.arrays["positions"], spec.robots.sigma, goals, trace.arrays["arrival_steps"], spec.workspace.build())
    return {**row, "cpu": cpu, "seed": seed}, np.asarray(trace.metadata["starts"]), goals


def explicit(mapping: dict, starts: np.ndarray, goals: np.ndarray, noise: bool) -> dict:
    """``mapping`` for robofleet's ORCA from the given starts and goals (exact positions unless ``noise``)."""
    robots = {**mapping["robots"], "layout": {"kind": "explicit", "starts": starts.tolist(), "goals": goals.tolist()}}
    workspace = dict(mapping["workspace"])
    if not noise:
        robots["sigma"], workspace["obstacle_sigma"] = 0.0, 0.0
    return {**mapping, "method": "orca", "robots": robots, "workspace": workspace, "orca": ORCA.model_dump()}


def orca_run(mapping: dict, seed: int) -> dict:
    cpu = time.process_time()
    spec = robofleet.load_scenario(mapping)
    trace = robofleet.simulate(spec, seed=seed)
    cpu = time.process_time() - cpu
    return {**judged(trace.arrays["positions"], spec.robots.sigma, np.asarray(trace.metadata["goals"]),
                     trace.arrays["arrival_steps"], spec.workspace.build()), "cpu": cpu, "seed": seed}


def rvo2_run(mapping: dict, starts: np.ndarray, goals: np.ndarray) -> dict:
    """RVO2 from the same starts with the same polygons and the same arrival rule."""
    import pyrvo

    cpu = time.process_time()
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
    cpu = time.process_time() - cpu
    return {**judged(track, 0.0, goals, arrivals, workspace), "cpu": cpu, "seed": -1}


def scene_rows(job: tuple[str, int, bool, bool]) -> dict:
    """Every method on one scene (only B-UAVC with ``buavc_only``): ``{method: figures}``."""
    generator, seed, orca_noise, buavc_only = job
    mapping = GENERATORS[generator](seed)
    try:
        row, starts, goals = buavc_run(mapping, seed)
    except ScenarioError as error:  # the antipodal sampler found no start for some robot
        return {"no layout": {"seed": seed, "error": str(error)}}
    if buavc_only:
        return {"B-UAVC": row}
    out = {"B-UAVC": row, "robofleet ORCA": orca_run(explicit(mapping, starts, goals, False), seed), "RVO2": rvo2_run(mapping, starts, goals)}
    if orca_noise:
        out["robofleet ORCA, noisy estimates"] = orca_run(explicit(mapping, starts, goals, True), seed)
    return out


# ---------------------------------------------------------------------------------------
# the table
# ---------------------------------------------------------------------------------------
HEADER = ("| scenes | method | home [CP 95 %] | all arrived once | robots home | travel time, paired [s] | contacts robot–robot / –obstacle / –wall (steps) | scenes with a contact | deepest overlap [mm] | CPU per scene, mean / max [s] |\n"
          "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")


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
                    f"{1e3 * max(r['deepest'] for r in runs):.3g} | {np.mean([r['cpu'] for r in runs]):.1f} / {max(r['cpu'] for r in runs):.1f} |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=20, help="scenes per generator")
    ap.add_argument("--first-seed", type=int, default=20000)
    ap.add_argument("--generators", nargs="+", choices=list(GENERATORS), default=list(GENERATORS))
    ap.add_argument("--orca-noise", action="store_true", help="also robofleet's ORCA on the scene's noisy estimates")
    ap.add_argument("--buavc-only", action="store_true", help="only B-UAVC (no ORCA, no RVO2)")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (results do not depend on it)")
    args = ap.parse_args()
    print(machine())
    print(HEADER)
    t0 = time.perf_counter()
    seeds = range(args.first_seed, args.first_seed + args.scenes)
    every: list[dict] = []
    for generator in args.generators:
        jobs = [(generator, s, args.orca_noise, args.buavc_only) for s in seeds]
        if args.jobs > 1:
            with ProcessPoolExecutor(args.jobs) as pool:
                scenes = list(pool.map(scene_rows, jobs))
        else:
            scenes = [scene_rows(j) for j in jobs]
        unplaced = [s["no layout"]["seed"] for s in scenes if "no layout" in s]
        scenes = [s for s in scenes if "no layout" not in s]
        every += scenes
        print("\n".join(table_rows(f"{generator} {seeds.start}–{seeds.stop - 1}", scenes)), flush=True)
        print(f"B-UAVC not home: {[s['B-UAVC']['seed'] for s in scenes if not s['B-UAVC']['home']]}; "
              f"no start layout (left out): {unplaced}", flush=True)
    if len(args.generators) > 1:
        print("\n".join(table_rows("all", every)))
    print(f"wall time: {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
