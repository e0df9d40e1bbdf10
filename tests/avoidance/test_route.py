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


def box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


def narrow_gap_route() -> tuple[route_module.Route, float]:
    """A wall of two boxes across a 6 × 4 m workspace with one gap of 1.1 m: wider than the
    2 c = 1.0 m the cells need, narrower than the 1.8 (c + passage) = 1.17 m the passage
    rule keeps open. The goal lies behind the wall."""
    clearance = 0.5
    polygons = [box(-0.25, 0.55, 0.25, 2.5), box(-0.25, -2.5, 0.25, -0.55)]
    roadmap = Roadmap(polygons, 1.15 * clearance, (-3.0, -2.0, 3.0, 2.0), clearance, passage=0.15)
    return route_module.Route(roadmap, np.array([[2.0, 1.2]])), clearance


def cells_fit(route: route_module.Route) -> Roadmap:
    """The roadmap of ``route``'s obstacles with only the gaps narrower than ``2 c`` closed."""
    r = route.roadmap
    return Roadmap(r.polygons, 1.15 * r.clearance, (-3.0, -2.0, 3.0, 2.0), r.clearance, 0.0, gap_factor=2.0)


def test_route_leads_through_a_gap_only_the_cells_can_pass():
    """Seeded estimates on the near side of the wall: the passage rule closes the only way,
    so the roadmap finds nothing; the route must still lead through the gap (a sub-goal
    visible from the estimate, not the goal behind the box, with a finite path length
    left), and once through, straight to the goal."""
    route, clearance = narrow_gap_route()
    near = route.roadmap.nodes[:, 0] < 0.0
    assert near.any() and np.all(np.isinf(route.costs[0, near])), "the passage rule closes the gap"
    narrow = cells_fit(route)
    rng = np.random.default_rng(7)
    for estimate in np.column_stack([rng.uniform(-2.4, -0.9, 40), rng.uniform(-1.4, 1.4, 40)]):
        sub, to_go = route.step(estimate[None])
        assert not np.allclose(sub[0], route.goals[0]), f"from {estimate} the route hands over the goal behind the box"
        assert np.isfinite(to_go[0]) and to_go[0] >= np.linalg.norm(route.goals[0] - estimate) - 1e-9
        seen_from = exit_points(estimate[None], narrow.sight)
        assert segments_free(seen_from, sub, narrow.sight)[0]
        assert sub[0, 0] <= clearance * 1.15 + 0.25 + 1e-9, "the sub-goal lies on the near side of the gap"
    beyond = np.array([[1.0, 0.0]])
    sub, to_go = route.step(beyond)
    np.testing.assert_allclose(sub, route.goals)
    assert to_go[0] == pytest.approx(np.linalg.norm(route.goals[0] - beyond[0]))
