"""A robot on its way back to its goal — returning from a yield, or holding away from its
goal without being home — follows the route round the obstacles, as a robot on its way
does; a robot that never left keeps holding."""

from __future__ import annotations

import numpy as np

from robofleet.avoidance import CellGeometry, ObstacleSet, build_cells, wall_planes
from robofleet.avoidance.navigation import NavigationParams, StepState, TeamNavigation
from robofleet.avoidance.navigation.progress import DeadlockParams
from robofleet.avoidance.navigation.route import Roadmap, Route
from robofleet.avoidance.navigation.yielding import RETURN

BOX = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
BOUNDS = np.array([[-5, -5], [5, -5], [5, 5], [-5, 5.0]])


def team(estimates, goals):
    """Two parked single integrators; a box between robot 0 and its goal."""
    nav = TeamNavigation("single_integrator", NavigationParams(), DeadlockParams(), len(goals), 0.4, 0.1, 0.1, 2.0)
    nav.route = Route(Roadmap([BOX], 0.7, (-5, -5, 5, 5), 0.6), goals)
    nav.goal.arrived[:] = True
    geometry = CellGeometry(ObstacleSet.build([BOX], [np.zeros((2, 2))], 0.0), *wall_planes(BOUNDS))
    cells = build_cells(estimates, np.zeros((len(goals), 2, 2)), np.full(len(goals), 0.2), 0.0, geometry, local_box=2.0)
    return nav, cells


def decide(nav, estimates, goals, cells) -> StepState:
    step = StepState(estimates, goals, cells, estimates)
    for stage in nav.stages[:5]:  # goal, route, detour, recovery, yielding
        stage(nav, step)
    return step


def test_a_returning_robot_takes_the_route_round_the_box():
    estimates, goals = np.array([[-2.0, 0.0], [3.0, 3.0]]), np.array([[2.0, 0.0], [3.0, 3.0]])
    nav, cells = team(estimates, goals)
    nav.parking.mode[0], nav.parking.mode_left[0] = RETURN, 200
    step = decide(nav, estimates, goals, cells)
    sub, _ = nav.route.step(estimates)
    assert step.moving[0] and not np.allclose(step.target[0], goals[0])
    np.testing.assert_allclose(step.target[0], sub[0])  # the route's sub-goal, not straight at the box
    assert not step.moving[1]  # at its goal: holds


def test_a_robot_holding_away_from_its_goal_drives_back_by_the_route():
    estimates, goals = np.array([[-2.0, 0.0], [3.0, 3.0]]), np.array([[2.0, 0.0], [3.0, 3.0]])
    nav, cells = team(estimates, goals)  # robot 0 holds (its return ran out) and is not home
    nav.goal.home[:] = [False, True]
    step = decide(nav, estimates, goals, cells)
    assert step.moving.tolist() == [True, False]
    np.testing.assert_allclose(step.target[0], nav.route.step(estimates)[0][0])
