"""Detours around still neighbours (:mod:`robofleet.avoidance.navigation.detour`): the re-plan is
the shortest path of brute force (shapely visibility, networkx Dijkstra) over the same
nodes, and a robot gets through a gap a parked robot closes by going round."""

import networkx as nx
import numpy as np
import pytest
from shapely.geometry import LineString, Polygon

import robofleet
from robofleet.avoidance.navigation.detour import (
    DetourParams,
    detour_graph,
    disc_polygons,
    shortest_first_step,
)
from robofleet.avoidance.navigation.route import Roadmap, exit_points, grown_polygons
from robofleet.avoidance.random_scenarios import random_convex_polygon


def brute_force_length(points, shapes, seen) -> float:
    """Shortest free path points[0] → points[1] over all the points (shapely, networkx),
    each segment tested between the ``seen`` points."""
    graph = nx.Graph()
    graph.add_nodes_from(range(len(points)))
    for i in range(len(points)):
        for j in range(i + 1, len(points)):
            p, q = points[i], points[j]
            if all(LineString([seen[i], seen[j]]).intersection(s).length < 1e-6 for s in shapes):
                graph.add_edge(i, j, weight=float(np.linalg.norm(p - q)))
    return nx.dijkstra_path_length(graph, 0, 1) if nx.has_path(graph, 0, 1) else np.inf


@pytest.mark.parametrize("seed", range(4))
def test_detour_is_the_shortest_path_around_obstacles_and_discs(seed):
    """|p̂ − first step| + the length left equals brute force over the same graph points,
    with the static sight polygons and the discs as obstacles (a goal inside a sight polygon
    is seen from where it leaves it); the discs' nodes avoid them."""
    rng = np.random.default_rng(200 + seed)
    polys = [np.asarray(random_convex_polygon(rng, rng.uniform(-3, 3, 2), rng.uniform(0.3, 0.8))) for _ in range(3)]
    clearance, radius = 0.4, 0.7
    roadmap = Roadmap(polys, 1.15 * clearance, (-5.0, -5.0, 5.0, 5.0), clearance)
    static = [Polygon(p) for p in grown_polygons(polys, 0.9 * clearance)]
    checked = 0
    for _ in range(6):
        start, goal, centres = rng.uniform(-4.5, 4.5, 2), rng.uniform(-4.5, 4.5, 2), rng.uniform(-4, 4, (2, 2))
        if any(s.contains(Polygon(disc_polygons(start[None], 0.01)[0])) for s in static):
            continue
        graph = detour_graph(roadmap, start, goal, centres, radius, DetourParams())
        shapes = static + [Polygon(d) for d in graph.discs]
        seen = graph.points.copy()  # estimate and goal: their segments start where they leave the sight polygons
        seen[:2] = exit_points(seen[:2], roadmap.sight)
        reference = brute_force_length(graph.points, shapes, seen)
        point, rest = shortest_first_step(graph)
        ours = np.inf if point is None else np.linalg.norm(point - start) + rest
        if np.isfinite(reference):
            assert ours == pytest.approx(reference, rel=1e-6, abs=1e-6)
            checked += 1
        else:
            assert point is None
    assert checked > 0


def test_a_disc_closing_the_only_gap_sends_the_route_round_the_other_way():
    """Two boxes leave a gap; with a still robot in it, the route goes round a box."""
    boxes = [np.array([[-0.5, 0.8], [0.5, 0.8], [0.5, 2.8], [-0.5, 2.8]]), np.array([[-0.5, -2.8], [0.5, -2.8], [0.5, -0.8], [-0.5, -0.8]])]
    roadmap = Roadmap(boxes, 0.65, (-5.0, -5.0, 5.0, 5.0), 0.55)
    start, goal = np.array([-2.0, 0.0]), np.array([2.0, 0.0])
    free = shortest_first_step(detour_graph(roadmap, start, goal, np.array([[0.0, 4.5]]), 0.73, DetourParams()))
    assert np.allclose(free[0], goal)  # a disc out of the way: straight through the gap
    point, rest = shortest_first_step(detour_graph(roadmap, start, goal, np.array([[0.0, 0.0]]), 0.73, DetourParams()))
    assert abs(point[1]) > 0.8  # off the gap's line, towards a corner of a box
    assert np.linalg.norm(point - start) + rest > 4.0 + 2 * 1.6  # round a box, not through the gap


def gap_mapping(detour: bool) -> dict:
    """Two boxes leave a 1.6 m gap, narrower than two robots' clearances; robot 0 is
    parked in it, robots 1 and 2 must cross from either side (so its step aside cancels)."""
    return {"family": "avoidance", "name": "gap", "method": "buavc", "max_steps": 900,
            "workspace": {"bounds": [-5, -5, 5, 5], "obstacle_sigma": 0.1,
                          "obstacles": [{"center": [0, 1.8], "size": [1, 2]}, {"center": [0, -1.8], "size": [1, 2]}]},
            "robots": {"n": 3, "radius": 0.2, "v_max": 0.4, "sigma": 0.1,
                       "layout": {"kind": "explicit", "starts": [[0, 0], [-3, 0.3], [3, -0.3]],
                                  "goals": [[0, 0], [3, 0.3], [-3, -0.3]]}},
            "navigation": {"enabled": True, "detour": {"enabled": detour}}}


def test_robots_go_round_a_parked_robot_that_closes_a_gap():
    """Closed loop, seeds 0–2: with detours every run succeeds without contact; without
    them, the two crossing robots stay stuck at the gap in most runs."""
    with_detour = [robofleet.simulate(robofleet.load_scenario(gap_mapping(True)), seed=s).results for s in range(3)]
    without = [robofleet.simulate(robofleet.load_scenario(gap_mapping(False)), seed=s).results for s in range(3)]
    assert all(r["success"] and r["collision_steps"] == 0 for r in with_detour)
    assert sum(r["success"] for r in without) < 3
