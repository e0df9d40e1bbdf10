"""Detours around still neighbours (:mod:`robofleet.avoidance.navigation.detour`): the re-plan is
the shortest path of brute force (shapely visibility, networkx Dijkstra) over the same
nodes, a gap too narrow to pass beside a still neighbour is closed, the discs sit at the
neighbours' running means, and a robot gets through a gap a parked robot closes by going round."""

import networkx as nx
import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import nearest_points

import robofleet
from robofleet.avoidance.navigation import detour
from robofleet.avoidance.navigation.detour import (
    DetourParams,
    Detours,
    YieldingParams,
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
        shapes = static + [Polygon(d) for d in graph.discs + graph.walls]
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


CLEARANCE, PAIR, PASSAGE = 0.61, 0.73, 0.15  # the random scenarios' c, 2β and 1.5 σ at σ = 0.1 m


def test_a_parked_robot_beside_an_obstacle_closes_the_gap_it_leaves():
    """A still neighbour 1.3 m from a box face: the robot needs 2β + c = 1.34 m there and
    room for the noise, yet the sight disc (0.66 m) and the box's sight polygon (0.55 m)
    leave a 9 cm sliver through which the straight line to the goal passes. With the
    passage wall the re-plan goes round the neighbour or the box; a neighbour 2 m from the
    face leaves the gap open (straight through)."""
    box = np.array([[-0.5, -2.0], [0.5, -2.0], [0.5, -0.5], [-0.5, -0.5]])
    roadmap = Roadmap([box], 1.15 * CLEARANCE, (-5.0, -5.0, 5.0, 5.0), CLEARANCE, PASSAGE)
    start, goal = np.array([-2.0, 0.1]), np.array([2.0, 0.1])
    point, rest = shortest_first_step(detour_graph(roadmap, start, goal, np.array([[0.0, 0.8]]), PAIR, DetourParams()))
    assert point[1] > 0.8 or point[1] < -2.0  # round the neighbour (past its centre) or the box, not into the gap
    assert np.linalg.norm(point - start) + rest > 4.5
    point, rest = shortest_first_step(detour_graph(roadmap, start, goal, np.array([[0.0, 1.5]]), PAIR, DetourParams()))
    assert np.allclose(point, goal)


@pytest.mark.parametrize("seed", range(6))
def test_exactly_the_gaps_narrower_than_the_passage_rule_are_walled_off(seed):
    """Property (seeded, adversarial: random convex obstacles, still neighbours placed at
    random distances around the passage width from the obstacles and from each other):
    with each neighbour an obstacle of radius 2β − c, every gap narrower than the route's
    passage width ``gap_factor (c + passage)`` gets a wall along its shortest segment,
    wider gaps none (shapely's exact distances to circles as the reference; gaps within
    2 cm of the width are not judged), and no finite edge of the detour graph crosses a wall."""
    rng = np.random.default_rng(500 + seed)
    polys = [np.asarray(random_convex_polygon(rng, rng.uniform(-3, 3, 2), rng.uniform(0.3, 0.8))) for _ in range(3)]
    roadmap = Roadmap(polys, 1.15 * CLEARANCE, (-5.0, -5.0, 5.0, 5.0), CLEARANCE, PASSAGE)
    width = roadmap.gap_factor * (CLEARANCE + PASSAGE)
    core = PAIR - CLEARANCE
    judged = 0
    for _ in range(5):
        anchor = Polygon(polys[rng.integers(len(polys))])
        near = np.asarray(nearest_points(anchor, Point(rng.uniform(-4, 4, 2)))[0].coords[0])
        first = near + rng.normal(size=2) / np.sqrt(2) * (core + rng.uniform(0.3, 1.5) * width)
        second = first + rng.normal(size=2) / np.sqrt(2) * (2 * core + rng.uniform(0.5, 1.5) * width)
        centres = np.array([first, second])
        graph = detour_graph(roadmap, rng.uniform(-4.5, 4.5, 2), rng.uniform(-4.5, 4.5, 2), centres, PAIR, DetourParams())
        walls = [Polygon(w) for w in graph.walls]
        cores = [Point(c).buffer(core, 64) for c in centres]
        pairs = [(a, b) for k, a in enumerate(cores) for b in cores[k + 1:] + [Polygon(q) for q in polys]]
        for a, b in pairs:
            gap = a.distance(b)
            if gap == 0.0 or abs(gap - width) < 0.02:
                continue
            middle = LineString(nearest_points(a, b)).interpolate(0.5, normalized=True)
            nearest_wall = min((w.distance(middle) for w in walls), default=np.inf)
            # the walls run along the octagons' shortest segments, a few cm off the circles'
            assert nearest_wall < 0.06 if gap < width else nearest_wall > 0.03
            judged += 1
        assert len(walls) <= len(pairs)
        seen = graph.points.copy()
        seen[:2] = exit_points(seen[:2], roadmap.sight)
        for i, j in zip(*np.nonzero(np.triu(np.isfinite(graph.lengths), 1))):
            assert all(LineString([seen[i], seen[j]]).intersection(w).length < 1e-6 for w in walls)
    assert judged > 0


def side_flips(anchored: bool, seed: int) -> int:
    """Sub-goal side changes of a blocked robot planning round a still neighbour 0.1 m off
    its line to the goal, whose estimate jitters with σ = 0.1 m, over 120 steps of detour."""
    rng = np.random.default_rng(seed)
    far_box = [np.array([[4.0, 4.0], [4.5, 4.0], [4.5, 4.5], [4.0, 4.5]])]
    roadmap = Roadmap(far_box, 1.15 * CLEARANCE, (-5.0, -5.0, 5.0, 5.0), CLEARANCE, PASSAGE)
    goals = np.array([[3.0, 0.0], [-4.0, -4.0]])
    detours = Detours(roadmap, goals, PAIR, 2.0, DetourParams(), YieldingParams())
    robot, neighbour = np.array([-1.0, 0.0]), np.array([0.0, 0.1])
    sides = []
    for _ in range(200):
        estimates = np.array([robot, neighbour + rng.normal(0.0, 0.1, 2)])
        if not anchored:
            detours.tracker.mean[:] = np.nan  # the latest estimate as the disc's centre (the tracker's mean restarts there)
            detours.tracker.observe(estimates, 1.0, 2)
            detours.tracker.still[:] = 10**6
        sub, _ = detours.apply(estimates, np.array([False, True]), goals.copy(), np.linalg.norm(goals - estimates, axis=1))
        if detours.active[0]:
            sides.append(np.sign(sub[0, 1]))
    assert len(sides) >= 120
    return int(np.sum(np.diff(sides[-120:]) != 0))


@pytest.mark.parametrize("seed", range(2))
def test_the_detour_side_follows_the_neighbours_mean_not_its_jitter(seed):
    """A still neighbour just off the robot's line to its goal: planned round its running
    mean, the sub-goal keeps one side for 120 steps; planned round its latest estimate,
    the side flips from step to step (the robot would dither in place)."""
    assert side_flips(True, seed) == 0
    assert side_flips(False, seed) > 10


def closed_gap_mapping() -> dict:
    """A box from the bottom up to y = −0.5 and a parked robot 1.25 m above its top face
    (the pair clearance plus the obstacle clearance is 1.34 m), with five more parked above
    it 0.8 m apart; robot 6 crosses from (−2, 0.2) to (2, 0.2), through the gap by the
    straight line. Yielding is off, so only a detour round the box gets it home."""
    parked = [[0.0, 0.75 + 0.8 * k] for k in range(6)]
    return {"family": "avoidance", "name": "closed_gap", "method": "buavc", "max_steps": 900,
            "workspace": {"bounds": [-5, -5, 5, 5], "obstacle_sigma": 0.1, "obstacles": [{"center": [0, -2.0], "size": [1, 3]}]},
            "robots": {"n": 7, "radius": 0.2, "v_max": 0.4, "sigma": 0.1,
                       "layout": {"kind": "explicit", "starts": parked + [[-2.0, 0.2]], "goals": parked + [[2.0, 0.2]]}},
            "navigation": {"yielding": {"enabled": False}}}


@pytest.mark.parametrize("seed", range(2))
def test_a_robot_goes_round_the_box_when_a_parked_robot_closes_the_gap_beside_it(seed):
    """Closed loop: the crossing robot detours round the box and every robot is home, without contact."""
    result = robofleet.simulate(robofleet.load_scenario(closed_gap_mapping()), seed=seed).results
    assert result["success"] and result["collision_steps"] == 0


@pytest.mark.slow
def test_without_the_passage_walls_the_robot_stays_at_the_closed_gap(monkeypatch):
    """The same scene, seeds 0–1, with the walls removed: the sight lines pass through the
    gap beside the parked robot and the crossing robot never gets home."""
    monkeypatch.setattr(detour, "passage_walls", lambda *args: [])
    results = [robofleet.simulate(robofleet.load_scenario(closed_gap_mapping()), seed=s).results for s in range(2)]
    assert not any(r["success"] for r in results)
