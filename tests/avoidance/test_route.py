"""Route stage: the sub-goal search tests nodes in order of cost to go and stops at the first
visible one; it picks what the exhaustive search over every node picks."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.avoidance.navigation import route as route_module
from robofleet.avoidance.navigation.route import Roadmap, exit_points, segments_free
from robofleet.avoidance.random_scenarios import room_scene
from robofleet.core.spec_blocks import ObstacleSpec


def room_roadmap(seed: int) -> tuple[Roadmap, np.ndarray]:
    """The roadmap of a ``room`` scene (pillars and walls) and the scene's goals."""
    mapping = room_scene(seed)
    polygons = [ObstacleSpec(**p).polygon() for p in mapping["workspace"]["obstacles"]]
    roadmap = Roadmap(polygons, 0.55, tuple(mapping["workspace"]["bounds"]), 0.48, passage=0.2)
    return roadmap, np.array(mapping["robots"]["layout"]["goals"])


def exhaustive(roadmap: Roadmap, estimates: np.ndarray, goals: np.ndarray, costs: np.ndarray):
    """The sub-goals by testing every node from every estimate (module docstring's rule)."""
    n, n_nodes = len(estimates), len(roadmap.nodes)
    seen_from = exit_points(estimates, roadmap.sight)
    goal_free = segments_free(seen_from, exit_points(goals, roadmap.sight), roadmap.sight)
    free = segments_free(np.repeat(seen_from, n_nodes, axis=0), np.tile(roadmap.nodes, (n, 1)), roadmap.sight).reshape(n, n_nodes)
    total = np.where(free, np.linalg.norm(estimates[:, None] - roadmap.nodes[None], axis=2) + costs, np.inf)
    best = np.argmin(total, axis=1)
    found = np.isfinite(total[np.arange(n), best])
    use_node = ~goal_free & found
    return np.where(use_node[:, None], roadmap.nodes[best], goals), np.where(use_node, costs[np.arange(n), best], 0.0), goal_free | found


@pytest.mark.parametrize("seed", [20000, 20003, 70005])
def test_ordered_search_picks_the_exhaustive_subgoal(seed):
    """Random estimates anywhere in the room (inside pillars too, and on nodes, where
    totals tie) and goals some nodes cannot reach: the same sub-goals, lengths and flags."""
    roadmap, goals = room_roadmap(seed)
    rng = np.random.default_rng(seed)
    costs = roadmap.costs_to_goals(goals)
    costs[:, rng.random(costs.shape[1]) < 0.1] = np.inf
    for _ in range(5):
        estimates = rng.uniform([-5.8, -2.8], [5.8, 2.8], (len(goals), 2))
        estimates[:2] = roadmap.nodes[rng.integers(len(roadmap.nodes), size=2)]
        got = roadmap.subgoals(estimates, goals, costs)
        for a, b in zip(got, exhaustive(roadmap, estimates, goals, costs)):
            np.testing.assert_array_equal(a, b)


def test_ordered_search_tests_a_fraction_of_the_segments(monkeypatch):
    """A robot that sees no goal tests its nodes best first, not all of them: in a room of
    pillars the step from the starts tests under half of the robot–node segments."""
    roadmap, goals = room_roadmap(20000)
    costs = roadmap.costs_to_goals(goals)
    tested = []

    def counting(a, b, obstacles):
        tested.append(len(a))
        return segments_free(a, b, obstacles)

    monkeypatch.setattr(route_module, "segments_free", counting)
    starts = np.array(room_scene(20000)["robots"]["layout"]["starts"])
    roadmap.subgoals(starts, goals, costs)
    assert sum(tested) - len(starts) < 0.5 * len(starts) * len(roadmap.nodes)


@pytest.mark.parametrize("seed", range(4))
def test_bounding_box_cull_gives_the_same_verdicts(seed):
    """Random convex polygons and random segments (some from a polygon's vertices, some
    of zero length): clipping only the pairs whose boxes meet gives every verdict that
    clipping all pairs gives."""
    from robofleet.avoidance.navigation.route import Halfplanes, halfplanes
    from robofleet.avoidance.random_scenarios import random_convex_polygon

    rng = np.random.default_rng(300 + seed)
    polygons = [np.asarray(random_convex_polygon(rng, rng.uniform(-3, 3, 2), rng.uniform(0.2, 1.0))) for _ in range(8)]
    planes = halfplanes(polygons)
    assert planes.lo is not None
    every_pair = Halfplanes(planes.A, planes.b)
    a, b = rng.uniform(-4, 4, (400, 2)), rng.uniform(-4, 4, (400, 2))
    a[:40] = np.concatenate(polygons)[rng.integers(sum(map(len, polygons)), size=40)]
    b[40:60] = a[40:60]
    np.testing.assert_array_equal(segments_free(a, b, planes), segments_free(a, b, every_pair))
    assert not segments_free(a, b, planes).all() and segments_free(a, b, planes).any()
