"""Small random instances for the coordination property tests."""

from __future__ import annotations

import numpy as np

from robofleet.core.errors import InfeasibleError
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.segment_graph import IncrementalCycleDetector, build_segment_layout
from robofleet.coordination.guarantees import check_theory
from robofleet.coordination.trajectories import make_trajectories


def line(a, b, speed, delay=0):
    """Constant-speed straight path from ``a`` to ``b`` after ``delay`` steps at ``a``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = int(np.ceil(np.linalg.norm(b - a) / speed)) + 1
    p = a + (b - a) * np.linspace(0.0, 1.0, n)[:, None]
    return np.vstack([np.repeat(p[:1], delay, axis=0), p])


def fig2_example():
    """Three robots of Figs. 2, 3 and 5: pairwise crossings around a small triangle.

    Plan order: robot 1 before 0 at their crossing, 2 before 0, 1 before 2.
    """
    paths = [line((-10, 0), (10, 0), 0.25, 8), line((-1, -6), (-1, 10), 0.25), line((3, -3), (-5, 9), 0.25, 20)]
    return make_trajectories(paths, 1.0, 0.1)


def random_instance(rng: np.random.Generator, n_robots: int, size: float | None = None, disjoint: bool | None = None,
                    max_tries: int = 2000, radius: float = 0.5, speed: float = 0.3, ring: bool = False):
    """A random collision-free, non-conflicting plan of straight lines with start delays.

    Start and goal points are drawn until no line passes within ``2r`` of another robot's
    start or goal (Definition 4); delays are then chosen robot by robot, the smallest
    that keeps the plan collision-free (a delay-only prioritized planner). ``disjoint=True``
    keeps only plans whose collision segments are disjoint (Theorem 4), ``False`` only
    plans where they are not, ``None`` either. ``ring=True`` puts starts on a circle and
    goals roughly opposite, so that paths crowd through the centre (many overlapping
    collision segments, where flips can close cycles).
    """
    size = size or (12.0 if ring else 6.0 + 3.0 * n_robots)
    for _ in range(max_tries):
        starts, goals = _ring(rng, n_robots, size) if ring else (rng.uniform(0, size, (n_robots, 2)), rng.uniform(0, size, (n_robots, 2)))
        if not _non_conflicting_lines(starts, goals, 2 * radius):
            continue
        paths = _delayed_paths(starts, goals, speed, radius, rng)
        traj = make_trajectories(paths, radius, 0.1)
        try:
            space = build_coordination_space(traj)
        except InfeasibleError:
            continue
        if space.n_obstacles < min(2, n_robots - 1):
            continue
        report = check_theory(traj, space)
        if not report.non_conflicting or (disjoint is not None and report.disjoint_segments != disjoint):
            continue
        layout = build_segment_layout(space)
        try:
            IncrementalCycleDetector(layout, space.initial_labels)
        except InfeasibleError:
            continue
        return traj, space, layout
    raise RuntimeError("no instance found")


def _ring(rng, n, size):
    angle = rng.permutation(n) * 2 * np.pi / n + rng.uniform(0, 0.4, n)
    goal_angle = angle + np.pi + rng.uniform(-0.6, 0.6, n)
    centre = np.full(2, size / 2) + rng.uniform(-0.5, 0.5, 2)
    unit = lambda a: np.column_stack([np.cos(a), np.sin(a)])  # noqa: E731
    return centre + size / 2 * unit(angle), centre + size / 2 * unit(goal_angle)


def _non_conflicting_lines(starts, goals, reach) -> bool:
    from robofleet.core.geometry import point_segment_distance

    n = len(starts)
    ends = np.concatenate([starts, goals])
    d = point_segment_distance(ends, starts, goals)  # (2n, n): endpoint vs each robot's line
    own = np.concatenate([np.arange(n), np.arange(n)])
    d[np.arange(2 * n), own] = np.inf
    return bool(np.all(d >= reach * 1.05)) and bool(np.all(np.linalg.norm(starts[:, None] - starts[None], axis=-1)[np.triu_indices(n, 1)] > reach))


def _delayed_paths(starts, goals, speed, radius, rng):
    """Smallest start delay per robot (random priority) that avoids the earlier robots' plans."""
    order = rng.permutation(len(starts))
    placed: list[np.ndarray] = []
    paths = [None] * len(starts)
    for i in order:
        base = line(starts[i], goals[i], speed)
        for delay in range(0, 400, 2):
            cand = np.vstack([np.repeat(base[:1], delay, axis=0), base])
            if all(_apart(cand, other, 2 * radius) for other in placed):
                break
        placed.append(cand)
        paths[i] = cand
    return paths


def _apart(a, b, reach) -> bool:
    t = max(len(a), len(b))
    pa = np.vstack([a, np.repeat(a[-1:], t - len(a), axis=0)])
    pb = np.vstack([b, np.repeat(b[-1:], t - len(b), axis=0)])
    return bool(np.all(np.linalg.norm(pa - pb, axis=1) >= reach))


def roundabout_instance(rng: np.random.Generator, n_robots: int, ring_radius: float = 6.0, spoke: float = 3.0,
                        speed: float = 0.3, radius: float = 0.5):
    """A roundabout: robot ``i`` comes in along a spoke at angle ``≈ 2πi/n``, drives
    counter-clockwise around the ring and leaves along its own exit spoke (exits halfway
    between entries, a random permutation), after the smallest start delay that keeps the
    plan collision-free (random priority). Robots follow each other around the ring, so
    their collision segments overlap in long chains; starts and goals stay on the spokes,
    away from the ring (Definition 4 holds)."""
    slot = 2 * np.pi / n_robots
    exits = rng.permutation(n_robots)
    paths = []
    for i in range(n_robots):
        a0 = i * slot + rng.uniform(-0.1, 0.1)
        a1 = a0 + ((exits[i] + 0.5) * slot - a0) % (2 * np.pi)
        inward = np.linspace(ring_radius + spoke, ring_radius, int(spoke / speed) + 1)[:, None] * [np.cos(a0), np.sin(a0)]
        angles = np.linspace(a0, a1, int(ring_radius * (a1 - a0) / speed) + 1)
        arc = ring_radius * np.column_stack([np.cos(angles), np.sin(angles)])
        outward = np.linspace(ring_radius, ring_radius + spoke, int(spoke / speed) + 1)[:, None] * [np.cos(a1), np.sin(a1)]
        paths.append(np.vstack([inward, arc[1:], outward[1:]]))
    placed, delayed = [], [None] * n_robots
    for i in rng.permutation(n_robots):
        for delay in range(0, 600, 2):
            cand = np.vstack([np.repeat(paths[i][:1], delay, axis=0), paths[i]])
            if all(_apart(cand, other, 2 * radius) for other in placed):
                break
        placed.append(cand)
        delayed[i] = cand
    traj = make_trajectories(delayed, radius, 0.1)
    return traj, build_coordination_space(traj)
