"""The route stage of :mod:`robofleet.avoidance.navigation.route`: exact against brute force on
small inputs, robots of every 2-D model get out of a trap the goal alone leads into, and
a gap a robot can enter but not pass counts as closed."""

import networkx as nx
import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon

import robofleet
from robofleet.avoidance.navigation.route import (
    Roadmap,
    exit_points,
    gap_blockers,
    grown_polygons,
    halfplanes,
    segments_free,
)
from robofleet.avoidance.random_scenarios import random_convex_polygon


def random_polygons(rng, count):
    return [np.asarray(random_convex_polygon(rng, rng.uniform(-3, 3, 2), rng.uniform(0.3, 1.0))) for _ in range(count)]


@pytest.mark.parametrize("seed", range(6))
def test_segment_test_matches_shapely(seed):
    """A segment is free exactly when its intersection with every polygon has no length
    (shapely's exact geometry as the reference)."""
    rng = np.random.default_rng(seed)
    polys = grown_polygons(random_polygons(rng, 4), 0.2)
    a, b = rng.uniform(-4, 4, (300, 2)), rng.uniform(-4, 4, (300, 2))
    ours = segments_free(a, b, halfplanes(polys))
    shapes = [Polygon(p) for p in polys]
    reference = np.array([all(LineString([p, q]).intersection(s).length < 1e-6 for s in shapes) for p, q in zip(a, b)])
    np.testing.assert_array_equal(ours, reference)


def brute_force_length(start, goal, roadmap: Roadmap, shapes) -> float:
    """Shortest free path start → goal over the roadmap's nodes (shapely visibility,
    networkx Dijkstra)."""
    points = [tuple(start), tuple(goal)] + [tuple(v) for v in roadmap.nodes]
    graph = nx.Graph()
    for i, p in enumerate(points):
        for j in range(i + 1, len(points)):
            q = points[j]
            if all(LineString([p, q]).intersection(s).length < 1e-6 for s in shapes):
                graph.add_edge(i, j, weight=float(np.hypot(p[0] - q[0], p[1] - q[1])))
    return nx.dijkstra_path_length(graph, 0, 1) if graph.has_node(0) and nx.has_path(graph, 0, 1) else np.inf


@pytest.mark.parametrize("seed", range(4))
def test_subgoal_cost_is_the_shortest_roadmap_path(seed):
    """‖p̂ − sub-goal‖ + D(sub-goal) equals the brute-force shortest path over the same
    nodes, for random obstacles, starts and goals."""
    rng = np.random.default_rng(100 + seed)
    polys = random_polygons(rng, 3)
    roadmap = Roadmap(polys, 0.5, (-5.0, -5.0, 5.0, 5.0), 0.4)
    shapes = [Polygon(p) for p in grown_polygons(polys, 0.9 * 0.4)]
    starts, goals = rng.uniform(-4.5, 4.5, (8, 2)), rng.uniform(-4.5, 4.5, (8, 2))
    outside = np.array([not any(s.intersects(Point(p)) for s in shapes) for p in np.vstack([starts, goals])])
    keep = outside[:8] & outside[8:]
    starts, goals = starts[keep], goals[keep]
    sub, rest, seen = roadmap.subgoals(starts, goals, roadmap.costs_to_goals(goals))
    ours = np.linalg.norm(sub - starts, axis=1) + rest
    reference = np.array([brute_force_length(s, g, roadmap, shapes) for s, g in zip(starts, goals)])
    finite = np.isfinite(reference)
    np.testing.assert_allclose(ours[finite], reference[finite], rtol=1e-9, atol=1e-9)
    assert seen[finite].all()


def cup(model: str, liveness: bool) -> dict:
    """A cup of three boxes open away from the goal, the robot inside it: heading straight
    for the goal presses it against the cup's bottom."""
    boxes = [{"center": [1.0, 0.0], "size": [0.4, 3.0]}, {"center": [-0.3, 1.3], "size": [2.2, 0.4]},
             {"center": [-0.3, -1.3], "size": [2.2, 0.4]}]
    m = {"family": "avoidance", "name": "cup", "method": "buavc", "max_steps": 600,
         "workspace": {"bounds": [-5, -5, 5, 5], "obstacle_sigma": 0.05, "obstacles": boxes},
         "robots": {"n": 1, "radius": 0.2, "v_max": 0.4 if model != "unicycle" else 0.6, "sigma": 0.05,
                    "layout": {"kind": "explicit", "starts": [[0.0, 0.0]], "goals": [[3.5, 0.3]]}},
         "navigation": {"enabled": liveness}}
    if model != "single_integrator":
        m["model"] = {"kind": model, "a_max": 1.0} if model == "double_integrator" else {"kind": model, "omega_max": 1.5707963}
    return m


@pytest.mark.parametrize("model", ["single_integrator", "double_integrator", "unicycle"])
def test_every_2d_model_leaves_the_cup_by_the_roadmap(model):
    out = robofleet.simulate(robofleet.load_scenario(cup(model, True)), seed=1).results
    assert out["success"] and out["collision_steps"] == 0


def test_without_the_roadmap_the_double_integrator_stays_in_the_cup():
    """The paper's controller (appendix C rotation only for double integrators) does not
    get out: the test above is not vacuous."""
    out = robofleet.simulate(robofleet.load_scenario(cup("double_integrator", False)), seed=1).results
    assert not out["success"]


@pytest.mark.parametrize("seed", range(5))
def test_exit_points_land_on_the_boundary_of_the_polygon_they_leave(seed):
    rng = np.random.default_rng(seed)
    polys = grown_polygons(random_polygons(rng, 1), 0.5)
    shape = Polygon(polys[0])
    points = rng.uniform(-4, 4, (400, 2))
    moved = exit_points(points, halfplanes(polys))
    inside = np.array([shape.contains(Point(p)) for p in points])
    assert inside.any()
    np.testing.assert_array_equal(moved[~inside], points[~inside])
    assert max(shape.exterior.distance(Point(p)) for p in moved[inside]) < 1e-5
    assert not any(shape.contains(Point(p)) for p in moved[inside])


def box(cx: float, cy: float, w: float, h: float) -> np.ndarray:
    return np.array([[cx - w / 2, cy - h / 2], [cx + w / 2, cy - h / 2], [cx + w / 2, cy + h / 2], [cx - w / 2, cy + h / 2]])


def gap(width: float, passage_sigmas: float = 1.5) -> dict:
    """One robot crossing between two boxes ``width`` apart (σ = 0.1 m: the cells keep
    0.61 m from each box, so the estimate has ``width − 1.21`` m to move in)."""
    h = width / 2
    return {"family": "avoidance", "name": "gap", "method": "buavc", "max_steps": 400,
            "workspace": {"bounds": [-5, -5, 5, 5], "obstacle_sigma": 0.1,
                          "obstacles": [{"center": [0, h + 0.5], "size": [0.6, 1.0]}, {"center": [0, -h - 0.5], "size": [0.6, 1.0]}]},
            "robots": {"n": 1, "radius": 0.2, "v_max": 0.4, "sigma": 0.1,
                       "layout": {"kind": "explicit", "starts": [[-3.0, 0.0]], "goals": [[3.0, 0.0]]}},
            "navigation": {"route": {"passage_sigmas": passage_sigmas}}}


@pytest.mark.parametrize("seed", range(3))
def test_a_gap_too_narrow_to_pass_is_closed_and_the_robot_goes_round(seed):
    out = robofleet.simulate(robofleet.load_scenario(gap(1.2)), seed=seed).results
    assert out["success"] and out["collision_steps"] == 0


def test_without_the_passage_margin_the_robot_sticks_in_the_gap():
    """The same gap with the roadmap at the cells' clearance: the test above is not vacuous."""
    assert not any(robofleet.simulate(robofleet.load_scenario(gap(1.2, passage_sigmas=0.0)), seed=s).results["success"] for s in range(3))


def test_gap_blockers_close_exactly_the_gaps_narrower_than_the_width():
    boxes = [box(0, 1.2, 0.6, 1.0), box(0, -1.2, 0.6, 1.0), box(3.0, 0.0, 0.6, 0.6)]  # gaps 1.4 m and ≥ 2.4 m
    assert len(gap_blockers(boxes, 1.39)) == 0
    (wall,) = gap_blockers(boxes, 1.41)
    assert Polygon(wall).intersects(LineString([(-1, 0), (1, 0)]))  # across the 1.4 m gap
    assert not segments_free(np.array([[-1.0, 0.0]]), np.array([[1.0, 0.0]]), halfplanes([wall]))[0]


def test_parking_targets_while_nobody_is_parked_are_the_goals_themselves():
    """While no robot has arrived the yielding rule leaves every target as it is: it
    returns the goals array itself (no copy) and nobody moves, and its trackers still
    advance and its modes and counts stay reset."""
    from robofleet.avoidance.navigation.params import YieldingParams
    from robofleet.avoidance.navigation.yielding import HOLD, ParkingState, parking_targets

    rng = np.random.default_rng(5)
    n = 200
    goals, state = rng.normal(size=(n, 2)) * 5.0, ParkingState.initial(n)
    for _ in range(4):
        target, moving = parking_targets(goals + rng.normal(size=(n, 2)), goals, np.zeros(n, bool), state, YieldingParams())
        assert target is goals and not moving.any()
        assert (state.mode == HOLD).all() and not state.linger.any() and not state.clear.any()
