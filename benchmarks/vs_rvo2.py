"""robofleet's ORCA and B-UAVC steps against RVO2's C++ ORCA (``pyrvo``), interleaved in one process.

Scenario (the same for all three): N robots evenly on a circle (spacing 4 r_s), each
heading for its antipode; r_s = 0.2 m, v_max = 0.4 m/s, Δt = 0.1 s, ORCA with 10
neighbours within 3 m and τ = 2 s. RVO2 and robofleet's ORCA see exact positions;
B-UAVC sees estimates with σ = 0.1 m (its cells carry the chance buffers) and runs twice:
as shipped (the default, navigation rules on) and as the paper's one-step controller
(``navigation: {enabled: false}``), each timed and reported in its own column.

Each round runs ``--steps`` steps of every method from the start, in turn (RVO2, then
robofleet's ORCA and both B-UAVC runs for each ``--threads`` count), and keeps each run's median
step time: RVO2's ``do_step`` (neighbour k-d tree, ORCA lines, LPs, position update);
robofleet's per-step time as ``simulate`` records it (``step_seconds``: the whole
team's ORCA velocities, or cells + projection + control). The ratios robofleet / RVO2 of
the rounds are printed as min / median / max, with the growth between sizes against
N log N (×13.3 from 1k to 10k, ×5.9 from 10k to 50k). A second table does the same on
a dense crowd (``orca_scale.py``'s jittered grid of spacing 0.45 m, random current
velocities, goals mirrored through the origin) where most agents need the infeasible-LP
fallback, and prints the largest velocity difference to RVO2 after one step from the same
state and after the 10 steps (RVO2 computes in single precision; in a dense crowd the
two runs drift apart over the steps, as any two roundings of the same run do). A third
table (``--clutter-sizes``) times the ORCA step among static obstacles: the circle swap
with a 1 × 1 m box 1.5 m inside the ring every 8 robots (N/8 boxes, in every robot's
obstacle range within the first steps), RVO2 with the same boxes as obstacle polygons,
robofleet's ORCA with them as :class:`~robofleet.avoidance.orca_obstacles.ObstacleEdges`,
both on exact positions, with the largest velocity difference after one step.

Threads: robofleet's kernels run on ``numba.get_num_threads()`` threads (set
``NUMBA_NUM_THREADS`` or pass ``--threads 1 2`` to measure both in the same run); RVO2's
wheel is built without OpenMP (one thread).

Clock (``--clock``): ``wall`` (the default) times the steps as above; ``cpu`` times the
circle swap's steps in CPU time of the process (``time.process_time``: RVO2's ``do_step``,
and robofleet's cells, navigation and control — the block ``step_seconds`` times), which
other jobs on a shared machine do not stretch; with ``--threads 1`` both sides then count
the work of one core.

Run: ``python benchmarks/vs_rvo2.py [--sizes 1000 10000 50000] [--crowd-sizes 1000 10000] [--clutter-sizes 1000 10000] [--rounds 3] [--threads 1 2] [--clock wall|cpu]``
(needs ``pip install 'robofleet[bench]'`` for ``pyrvo``).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from itertools import pairwise
from unittest import mock

import numba
import numpy as np
from _machine import machine, nlogn_growth

import robofleet
from robofleet.avoidance.orca import OrcaParams, orca_velocities, preferred_velocities
from robofleet.avoidance.orca_obstacles import ObstacleEdges
from robofleet.avoidance.world import World

RADIUS, V_MAX, DT = 0.2, 0.4, 0.1
ORCA = OrcaParams(neighbor_dist=3.0, max_neighbors=10, time_horizon=2.0, time_horizon_obst=2.0)
PAPER_CONTROLLER = {"navigation": {"enabled": False}}
"""The scenario keys that switch the navigation rules off (the paper's one-step controller)."""
B_UAVC = {"B-UAVC": {}, "B-UAVC paper": PAPER_CONTROLLER}
"""The two B-UAVC runs timed: as shipped (the default) and the paper's controller."""
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def circle(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Starts and antipodal goals of ``n`` robots on a circle of spacing 4 r_s."""
    rho = max(4.0, n * 4 * RADIUS / (2 * math.pi))
    angle = 2 * np.pi * np.arange(n) / n
    ring = rho * np.column_stack([np.cos(angle), np.sin(angle)])
    return ring, -ring


def crowd(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``orca_scale.py``'s dense crowd: positions, current velocities, goals."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n] * 0.45
    return grid + rng.normal(size=grid.shape) * 0.02, rng.normal(size=grid.shape) * 0.1, -grid


def scenario(n: int, steps: int, method: str, sigma: float, extra: dict | None = None) -> robofleet.avoidance.Spec:
    """The circle swap as a scenario, with the defaults unless ``extra`` keys say otherwise
    (:data:`PAPER_CONTROLLER`: the paper's one-step controller, appendix C)."""
    rho = max(4.0, n * 4 * RADIUS / (2 * math.pi))
    half = rho + 2.0
    return robofleet.load_scenario({
        "family": "avoidance", "name": f"circle-{n}", "method": method, "max_steps": steps, "dt": DT,
        "workspace": {"bounds": [-half, -half, half, half]}, "record_cells": False, "orca": ORCA.model_dump(),
        "robots": {"n": n, "radius": RADIUS, "v_max": V_MAX, "sigma": sigma, "layout": {"kind": "circle", "radius": rho}},
        **(extra or {}),
    })


# ---------------------------------------------------------------------------------------
# RVO2
# ---------------------------------------------------------------------------------------
def rvo2_simulator(starts: np.ndarray, velocities: np.ndarray | None = None, obstacles: list[np.ndarray] = ()):
    import pyrvo

    sim = pyrvo.RVOSimulator(DT, ORCA.neighbor_dist, ORCA.max_neighbors, ORCA.time_horizon, ORCA.time_horizon_obst, RADIUS, V_MAX)
    for polygon in obstacles:  # counter-clockwise
        sim.add_obstacle([(float(x), float(y)) for x, y in polygon])
    if len(obstacles):
        sim.process_obstacles()
    for k, p in enumerate(starts):
        if velocities is None:
            sim.add_agent((float(p[0]), float(p[1])))
        else:
            sim.add_agent((float(p[0]), float(p[1])), ORCA.neighbor_dist, ORCA.max_neighbors, ORCA.time_horizon, ORCA.time_horizon_obst,
                          RADIUS, V_MAX, (float(velocities[k, 0]), float(velocities[k, 1])))
    return sim


def rvo2_positions(sim) -> np.ndarray:
    return np.array([sim.get_agent_position(i).to_tuple() for i in range(sim.get_num_agents())])


def rvo2_velocities(sim) -> np.ndarray:
    return np.array([sim.get_agent_velocity(i).to_tuple() for i in range(sim.get_num_agents())])


def rvo2_run(starts: np.ndarray, goals: np.ndarray, steps: int, velocities: np.ndarray | None = None,
             obstacles: list[np.ndarray] = (), clock: str = "wall") -> tuple[float, object]:
    """Median seconds of ``do_step`` over ``steps`` steps (preferred velocities set untimed)."""
    sim = rvo2_simulator(starts, velocities, obstacles)
    seconds, now = [], CLOCKS[clock]
    for _ in range(steps):
        pref = preferred_velocities(rvo2_positions(sim), goals, V_MAX, DT)
        for i, v in enumerate(pref):
            sim.set_agent_pref_velocity(i, (float(v[0]), float(v[1])))
        t0 = now()
        sim.do_step()
        seconds.append(now() - t0)
    return float(np.median(seconds)), sim


# ---------------------------------------------------------------------------------------
# robofleet
# ---------------------------------------------------------------------------------------
def robofleet_run(spec, threads: int, clock: str = "wall") -> float:
    """Median ``step_seconds`` of one ``simulate`` run on ``threads`` numba threads, or
    (``clock="cpu"``) the median CPU time of the same block, :meth:`World.decide`."""
    numba.set_num_threads(threads)
    if clock == "wall":
        trace = robofleet.simulate(spec, seed=0)
        return float(np.median(trace.arrays["step_seconds"]))
    with step_cpu_seconds() as seconds:
        robofleet.simulate(spec, seed=0)
    return float(np.median(seconds))


@contextmanager
def step_cpu_seconds() -> Iterator[list[float]]:
    """The CPU time of every :meth:`World.decide` call in the block (the step that
    ``step_seconds`` times: cells, navigation and control), appended to the list yielded."""
    seconds, decide = [], World.decide

    def timed(world, *args):
        t0 = time.process_time()
        out = decide(world, *args)
        seconds.append(time.process_time() - t0)
        return out

    with mock.patch.object(World, "decide", timed):
        yield seconds


def orca_crowd_run(starts, velocities, goals, steps: int, threads: int, obstacles: ObstacleEdges | None = None) -> tuple[float, np.ndarray]:
    """Median seconds of robofleet's ORCA step (velocities + position update) on the crowd."""
    numba.set_num_threads(threads)
    pos, vel, seconds = starts.copy(), velocities.copy(), []
    for _ in range(steps):
        pref = preferred_velocities(pos, goals, V_MAX, DT)
        t0 = time.perf_counter()
        vel, _ = orca_velocities(pos, vel, pref, RADIUS, V_MAX, ORCA, DT, obstacles)
        pos = pos + vel * DT
        seconds.append(time.perf_counter() - t0)
    return float(np.median(seconds)), vel


# ---------------------------------------------------------------------------------------
# the tables
# ---------------------------------------------------------------------------------------
def spread(values: list[float]) -> str:
    return f"{min(values):.2f} / {float(np.median(values)):.2f} / {max(values):.2f}"


def circle_table(sizes, rounds, steps, threads, clock: str = "wall") -> None:
    print(f"\ncircle swap, {steps} steps per run, {rounds} rounds, {clock} time; B-UAVC = the default (navigation rules on), "
          "B-UAVC paper = the paper's controller; ratio = robofleet step / RVO2 do_step (min / median / max)")
    labels = ["ORCA", *B_UAVC]
    head = f"{'robots':>8} {'RVO2 ms':>9}"
    for t in threads:
        for label in labels:
            head += f" {label + ' ms':>16} {label + '/RVO2 (' + str(t) + 't)':>26}"
    print(head)
    medians: dict[str, list[float]] = {}
    for n in sizes:
        starts, goals = circle(n)
        specs = {"ORCA": scenario(n, steps, "orca", 0.0), **{label: scenario(n, steps, "buavc", 0.1, extra) for label, extra in B_UAVC.items()}}
        rvo, times = [], {(m, t): [] for m in specs for t in threads}
        for _ in range(rounds):
            rvo.append(rvo2_run(starts, goals, steps, clock=clock)[0])
            for t in threads:
                for m, spec in specs.items():
                    times[m, t].append(robofleet_run(spec, t, clock))
        line = f"{n:>8} {np.median(rvo) * 1e3:>9.2f}"
        medians.setdefault("RVO2", []).append(float(np.median(rvo)))
        for t in threads:
            for m in labels:
                ratios = [a / b for a, b in zip(times[m, t], rvo)]
                medians.setdefault(f"{m} ({t}t)", []).append(float(np.median(times[m, t])))
                line += f" {np.median(times[m, t]) * 1e3:>16.2f} {spread(ratios):>26}"
        print(line, flush=True)
    growth_table(sizes, medians)
    if len(threads) > 1:
        for m in labels:
            base = medians[f"{m} ({threads[0]}t)"]
            for t in threads[1:]:
                gains = [a / b for a, b in zip(base, medians[f"{m} ({t}t)"])]
                print(f"{m} speed-up {threads[0]} → {t} threads: " + ", ".join(f"{n:,}: ×{g:.2f}" for n, g in zip(sizes, gains)))


def growth_table(sizes, medians) -> None:
    if len(sizes) < 2:
        return
    ref = [f"×{nlogn_growth(a, b):.1f}" for a, b in pairwise(sizes)]
    print("growth of the median step " + ", ".join(f"{a:,} → {b:,}" for a, b in pairwise(sizes)) + f" (N log N: {', '.join(ref)})")
    for name, values in medians.items():
        print(f"  {name:>14}: " + ", ".join(f"×{b / a:.1f}" for a, b in pairwise(values)))


def crowd_table(sizes, rounds, steps, threads) -> None:
    print(f"\ndense crowd, {steps} steps per run, {rounds} rounds; ratio = robofleet ORCA step / RVO2 do_step (min / median / max)")
    print(f"{'agents':>8} {'in fallback':>12} {'RVO2 ms':>9}" + "".join(f" {'ORCA ms':>9} {'ratio (' + str(t) + 't)':>20}" for t in threads)
          + f" {'|Δv| 1 step':>12} {'|Δv| 10 steps':>14}")
    for n in sizes:
        starts, vel0, goals = crowd(n)
        pref = preferred_velocities(starts, goals, V_MAX, DT)
        share = float(orca_velocities(starts, vel0, pref, RADIUS, V_MAX, ORCA, DT)[1].mean())
        one = one_step_gap(starts, vel0, goals)
        rvo, times, gap = [], {t: [] for t in threads}, 0.0
        for _ in range(rounds):
            seconds, sim = rvo2_run(starts, goals, steps, vel0)
            rvo.append(seconds)
            for t in threads:
                seconds, vel = orca_crowd_run(starts, vel0, goals, steps, t)
                times[t].append(seconds)
            gap = float(np.abs(vel - rvo2_velocities(sim)).max())
        line = f"{n:>8} {share:>12.1%} {np.median(rvo) * 1e3:>9.2f}"
        for t in threads:
            line += f" {np.median(times[t]) * 1e3:>9.2f} {spread([a / b for a, b in zip(times[t], rvo)]):>20}"
        print(line + f" {one:>12.1e} {gap:>14.1e}", flush=True)


def clutter(n: int) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The circle swap with a 1 × 1 m box 1.5 m inside the ring between every 8th pair of robots."""
    starts, goals = circle(n)
    rho = float(np.linalg.norm(starts[0]))
    angle = 2 * np.pi * (8 * np.arange(n // 8) + 4) / n
    square = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    return starts, goals, [(rho - 1.5) * np.array([np.cos(a), np.sin(a)]) + square for a in angle]


def clutter_table(sizes, rounds, steps, threads) -> None:
    print(f"\ncircle swap among boxes, {steps} steps per run, {rounds} rounds, exact positions; "
          "ratio = robofleet ORCA step / RVO2 do_step (min / median / max)")
    print(f"{'robots':>8} {'boxes':>7} {'RVO2 ms':>9}" + "".join(f" {'ORCA ms':>9} {'ratio (' + str(t) + 't)':>20}" for t in threads)
          + f" {'|Δv| 1 step':>12}")
    for n in sizes:
        starts, goals, boxes = clutter(n)
        edges = ObstacleEdges(boxes)
        zero = np.zeros_like(starts)
        rvo, times = [], {t: [] for t in threads}
        for _ in range(rounds):
            rvo.append(rvo2_run(starts, goals, steps, zero, boxes)[0])
            for t in threads:
                times[t].append(orca_crowd_run(starts, zero, goals, steps, t, edges)[0])
        _, sim = rvo2_run(starts, goals, 1, zero, boxes)
        ours, _ = orca_velocities(starts, zero, preferred_velocities(starts, goals, V_MAX, DT), RADIUS, V_MAX, ORCA, DT, edges)
        line = f"{n:>8} {len(boxes):>7} {np.median(rvo) * 1e3:>9.2f}"
        for t in threads:
            line += f" {np.median(times[t]) * 1e3:>9.2f} {spread([a / b for a, b in zip(times[t], rvo)]):>20}"
        print(line + f" {float(np.abs(ours - rvo2_velocities(sim)).max()):>12.1e}", flush=True)


def one_step_gap(starts, velocities, goals) -> float:
    """Largest velocity difference to RVO2 after one step from the same (single-precision) state."""
    _, sim = rvo2_run(starts, goals, 1, velocities)
    pos, vel = starts.astype(np.float32).astype(float), velocities.astype(np.float32).astype(float)
    pref = preferred_velocities(pos, goals, V_MAX, DT).astype(np.float32).astype(float)
    return float(np.abs(orca_velocities(pos, vel, pref, RADIUS, V_MAX, ORCA, DT)[0] - rvo2_velocities(sim)).max())


# ---------------------------------------------------------------------------------------
# reference trajectories for the agreement test (tests/avoidance/test_orca_kernel.py)
# ---------------------------------------------------------------------------------------
def reference_cases() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Small cases ``name -> (starts, velocities, goals)``: a head-on pair, a square swap,
    a circle of 8, 12 random agents, and a 6 × 6 crowd (spacing 0.45 m) where most
    agents need the infeasible-program fallback."""
    sq = np.array([[-1.5, -1.5], [1.5, -1.5], [1.5, 1.5], [-1.5, 1.5]]) + np.array([[0.02, 0], [0, 0.03], [-0.01, 0], [0, -0.02]])
    ang = 2 * np.pi * np.arange(8) / 8 + 0.01 * np.arange(8)
    ring = 2.0 * np.column_stack([np.cos(ang), np.sin(ang)])
    rng = np.random.default_rng(3)
    scattered = rng.uniform(-3, 3, (12, 2))
    pos, vel, goals = crowd(36)
    shift = pos.mean(axis=0)
    return {
        "head_on": (np.array([[-2.0, 0.05], [2.0, -0.05]]), np.zeros((2, 2)), np.array([[2.0, 0.05], [-2.0, -0.05]])),
        "square_swap": (sq, np.zeros((4, 2)), -sq),
        "circle_8": (ring, np.zeros((8, 2)), -ring),
        "random_12": (scattered, rng.normal(size=(12, 2)) * 0.1, -scattered),
        "crowd_36": (pos - shift, vel, goals + shift),
    }


def write_reference(path: str, steps: int = 10) -> None:
    """RVO2's positions ``(steps + 1, N, 2)`` and velocities of every reference case."""
    out = {}
    for name, (starts, velocities, goals) in reference_cases().items():
        sim = rvo2_simulator(starts, velocities)
        positions, vel = [rvo2_positions(sim)], [rvo2_velocities(sim)]
        for _ in range(steps):
            pref = preferred_velocities(positions[-1], goals, V_MAX, DT)
            for i, v in enumerate(pref):
                sim.set_agent_pref_velocity(i, (float(v[0]), float(v[1])))
            sim.do_step()
            positions.append(rvo2_positions(sim))
            vel.append(rvo2_velocities(sim))
        out[f"{name}/positions"], out[f"{name}/velocities"], out[f"{name}/goals"] = np.array(positions), np.array(vel), goals
    np.savez_compressed(path, **out)
    print(f"wrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write-reference", metavar="PATH", help="write RVO2's trajectories of the agreement test's cases and stop")
    ap.add_argument("--sizes", type=int, nargs="*", default=[1000, 10000, 50000])
    ap.add_argument("--crowd-sizes", type=int, nargs="*", default=[1000, 10000])
    ap.add_argument("--clutter-sizes", type=int, nargs="*", default=[1000, 10000])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--threads", type=int, nargs="+", default=[numba.get_num_threads()])
    ap.add_argument("--clock", choices=sorted(CLOCKS), default="wall", help="time the circle swap's steps in wall or CPU time")
    args = ap.parse_args()
    if args.write_reference:
        write_reference(args.write_reference)
        return
    print(machine())
    robofleet.simulate(scenario(100, 3, "orca", 0.0), seed=0)  # compile (or load) the kernels once
    for extra in B_UAVC.values():
        robofleet.simulate(scenario(100, 3, "buavc", 0.1, extra), seed=0)
    warm_starts, warm_goals, warm_boxes = clutter(100)
    orca_crowd_run(warm_starts, np.zeros_like(warm_starts), warm_goals, 2, numba.get_num_threads(), ObstacleEdges(warm_boxes))
    if args.sizes:
        circle_table(args.sizes, args.rounds, args.steps, args.threads, args.clock)
    if args.crowd_sizes:
        crowd_table(args.crowd_sizes, args.rounds, args.steps, args.threads)
    if args.clutter_sizes:
        clutter_table(args.clutter_sizes, args.rounds, args.steps, args.threads)


if __name__ == "__main__":
    main()
