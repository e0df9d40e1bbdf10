"""Liveness (issue 10): roadmap sub-goals, the right-hand turn and parked robots that
yield — and the command never leaves the cell."""

import numpy as np
import pytest

import robofleet
from robofleet.avoidance import CellGeometry, ObstacleSet, build_cells, wall_planes
from robofleet.avoidance.cell import Cells, Kind
from robofleet.avoidance.navigation import NavigationParams, TeamNavigation
from robofleet.avoidance.navigation.band import out_of_the_band
from robofleet.avoidance.navigation.goal import GoalChecker
from robofleet.avoidance.navigation.progress import DeadlockParams
from robofleet.avoidance.navigation.yielding import (
    HOLD,
    RETURN,
    YIELD,
    ParkingState,
    YieldingParams,
    parking_targets,
)
from robofleet.avoidance.projection import project_onto_cells

BOUNDS = np.array([[-5, -5], [5, -5], [5, 5], [-5, 5.0]])


@pytest.mark.parametrize("seed", range(12))
def test_yielding_commands_stay_inside_random_cells(seed):
    """Property: on random cells (random crowds, covariances, an uncertain box), every
    robot whose estimate lies in its cell — parked robots stepping aside included —
    commands a step that ends in its cell, at most v_max long."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 40))
    est = rng.uniform(-4.5, 4.5, (n, 2))
    sigma = rng.uniform(0.0, 0.15)
    covs = np.broadcast_to(sigma**2 * np.eye(2), (n, 2, 2))
    box = rng.uniform(-3, 3, 2) + np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    geo = CellGeometry(ObstacleSet.build([box], [0.01 * np.eye(2)], 0.05), *wall_planes(BOUNDS))
    cells = build_cells(est, covs, np.full(n, 0.2), 1.6, geo, local_box=2.0)
    goals = est + rng.normal(0, 0.05, (n, 2))  # most robots parked next to their goals
    goals[: n // 3] = -est[: n // 3]
    params = YieldingParams(near=1.5, linger_steps=1, aside=rng.uniform(0.2, 1.5), clear_steps=5)
    nav = TeamNavigation("single_integrator", NavigationParams(yielding=params), DeadlockParams(), n, 0.4, 0.1, 0.1, 2.0)
    for _ in range(3):  # hold → yield → keep yielding
        u = nav.command(est, goals, cells).u
        inside_now = cells.contains(est)
        assert np.all(cells.contains(est + 0.1 * u)[inside_now])
        assert np.all(np.linalg.norm(u, axis=1) <= 0.4 + 1e-12)
    assert (nav.parking.mode == YIELD).any()  # the property was exercised on yielding robots
    assert np.any(np.linalg.norm(u[nav.arrived], axis=1) > 0)


def test_parked_robot_yields_while_a_neighbour_lingers_then_returns():
    """HOLD until the neighbour has lingered linger_steps; YIELD (to the neighbour's left,
    aside_turn = 90°) while it stays near; RETURN clear_steps after it left, until the
    estimate is back at the goal (here at once: the estimates stay put); then HOLD."""
    est = np.array([[0.0, 0.0], [0.5, 0.0]])
    goals = est.copy()
    parked = np.array([True, False])
    state = ParkingState.initial(2)
    params = YieldingParams(near=1.0, linger_steps=3, aside=0.6, aside_turn=90.0, clear_steps=2, return_steps=3)
    modes = []
    for k in range(14):
        if k == 4:
            est[1] = [5.0, 0.0]  # the neighbour leaves
        target, moving = parking_targets(est, goals, parked, state, params)
        modes.append(int(state.mode[0]))
        if state.mode[0] == YIELD:
            np.testing.assert_allclose(target[0], [0.0, -0.6], atol=1e-12)  # away from it, turned 90° counter-clockwise
    assert modes == [HOLD, HOLD] + [YIELD] * 3 + [RETURN] + [HOLD] * 8
    assert state.mode[1] == HOLD and not moving[1]  # a robot that has not arrived never yields


def test_a_returning_robot_drives_until_it_is_back_at_its_goal():
    est, goals = np.array([[0.0, -1.0]]), np.zeros((1, 2))
    state = ParkingState.initial(1)
    state.mode[:], state.mode_left[:] = RETURN, 200
    checker = GoalChecker.initial(1, 0.1)
    for k in range(10):
        est[0, 1] = -1.0 + 0.1 * k  # driving back, 0.1 m a step
        checker.observe(est, goals)
        target, moving = parking_targets(est, goals, np.array([True]), state, YieldingParams(), tolerance=0.1)
        checker.settle(state.mode == HOLD)
        assert moving[0] == (k < 9)
        assert checker.all_home() == (k >= 9)  # home once back within the tolerance, holding
        np.testing.assert_allclose(target[0], goals[0])


def test_a_run_ends_only_when_every_robot_is_back_at_its_goal():
    """Latched arrival alone would end a run with a robot stepped aside, up to max_aside
    from its goal: the run goes on until every yield is over."""
    for seed in range(3):
        out = robofleet.simulate(robofleet.load_scenario(trap_mapping(True)), seed=seed)
        final = np.linalg.norm(out.positions[-1] - np.asarray(out.metadata["goals"]), axis=1)
        assert out.results["success"] and final.max() < 3 * 0.1 + 4 * 0.1  # 3 × tolerance on the estimate + 4σ


def test_a_yielding_robot_moves_further_aside_but_never_beyond_max_aside():
    est = np.array([[0.0, 0.0], [0.4, 0.0]])
    goals = est.copy()
    state = ParkingState.initial(2)
    params = YieldingParams(near=1.0, linger_steps=2, aside=0.5, aside_turn=0.0, max_aside=1.2)
    for _ in range(40):
        target, _ = parking_targets(est, goals, np.array([True, False]), state, params)
        assert np.linalg.norm(target[0] - goals[0]) <= 1.2 + 1e-12
    np.testing.assert_allclose(target[0], [-1.2, 0.0])


def trap_mapping(liveness: bool) -> dict:
    """A corridor 2.8 m wide; two robots parked at their goals 0.95 m apart across it.
    A third robot must pass between them: it needs about 1.45 m, and the lanes beside
    them are narrower than its clearance, so there is no way around."""
    m = {"family": "avoidance", "name": "trap", "method": "buavc", "max_steps": 500,
         "workspace": {"bounds": [-4, -1.4, 4, 1.4]},
         "robots": {"n": 3, "radius": 0.2, "v_max": 0.4, "sigma": 0.1,
                    "layout": {"kind": "explicit", "starts": [[0, 0.475], [0, -0.475], [-3, 0]],
                               "goals": [[0, 0.475], [0, -0.475], [3, 0]]}},
         "navigation": {"enabled": liveness}}
    return m


def trap(liveness: bool, seed: int) -> dict:
    return robofleet.simulate(robofleet.load_scenario(trap_mapping(liveness)), seed=seed).results


@pytest.mark.parametrize("seed", range(3))
def test_two_parked_robots_trap_only_yielding_escapes(seed):
    before, after = trap(False, seed), trap(True, seed)
    assert not before["success"] and before["arrived"] < 1.0
    assert after["success"] and after["collision_steps"] == 0


def test_liveness_is_on_by_default_and_off_changes_nothing_else():
    """Off, its parameters are ignored: the paper's controller, bit for bit."""
    assert robofleet.load_scenario("scenarios/avoidance/three_boxes.yaml").navigation.enabled
    off = {"max_steps": 80, "navigation": {"enabled": False}}
    a = robofleet.simulate(robofleet.load_scenario("scenarios/avoidance/three_boxes.yaml", overrides=off), seed=4)
    b = robofleet.simulate(robofleet.load_scenario("scenarios/avoidance/three_boxes.yaml",
                                                   overrides={**off, "navigation": {"enabled": False, "yielding": {"aside": 0.9, "near": 0.3}}}), seed=4)
    np.testing.assert_array_equal(a.arrays["positions"], b.arrays["positions"])


def test_same_seed_same_trace_with_liveness():
    spec = robofleet.load_scenario("scenarios/avoidance/ten_boxes.yaml", overrides={"max_steps": 120, "navigation": {"enabled": True}})
    t1, t2 = robofleet.simulate(spec, seed=3), robofleet.simulate(spec, seed=3)
    np.testing.assert_array_equal(t1.arrays["positions"], t2.arrays["positions"])


@pytest.mark.parametrize("seed", [0, 1000, 3000, 12345])
def test_random_scenario_is_reproducible_and_uses_the_shipped_budget_rule(seed):
    """Same seed ⇒ same mapping; 8–16 robots; convex obstacles inside the workspace;
    ``max_steps`` is the straight-line rule of the shipped scenarios."""
    from shapely.geometry import Polygon

    from robofleet.avoidance.random_scenarios import OBSTACLES, ROBOTS, random_scenario
    from robofleet.avoidance.spec import straight_line_budget

    mapping = random_scenario(seed)
    assert mapping == random_scenario(seed) and mapping != random_scenario(seed + 1)
    spec = robofleet.load_scenario(mapping)
    assert ROBOTS[0] <= spec.robots.n <= ROBOTS[1]
    polygons = spec.workspace.obstacle_polygons()
    assert OBSTACLES[0] <= len(polygons) <= OBSTACLES[1]
    for p in polygons:
        shape = Polygon(p)
        assert shape.is_valid and abs(shape.convex_hull.area - shape.area) < 1e-9 and np.all(np.abs(p) < 5.0)
    assert spec.max_steps == straight_line_budget(spec)


def band_cells() -> Cells:
    """One robot's cell: x ≤ 0 (an obstacle's face) and y ≤ 1 (a neighbour's)."""
    A = np.array([[[1.0, 0.0], [0.0, 1.0]]])
    return Cells(A, np.array([[0.0, 1.0]]), np.ones((1, 2), bool), np.array([[Kind.OBSTACLE, Kind.ROBOT]]), np.zeros((1, 2), np.int64))


@pytest.mark.parametrize("beyond, back", [(0.3, True), (0.1, False)])
def test_an_estimate_deep_beyond_an_obstacle_face_steers_back_into_the_cell(beyond, back):
    """0.3 m beyond the face (depth 0.2 m): the target is the cell's nearest point, not the
    projected goal; 0.1 m beyond it the projected goal stays."""
    cells, estimate, goal = band_cells(), np.array([[beyond, 0.5]]), np.array([[0.0, 3.0]])
    proj = project_onto_cells(goal, cells)
    out = out_of_the_band(estimate, proj, cells, 0.2)
    np.testing.assert_allclose(out.point, [[0.0, 0.5]] if back else proj.point)
    np.testing.assert_array_equal(out.active, proj.active)
