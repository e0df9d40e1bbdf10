"""The goal checker: ``success`` and ``arrived`` mean every robot is home at the end — its
own estimate within the goal tolerance when it last held — and the summary reports the
true distance to the goal. A robot whose return from a yield ran out of time holds where
it stands and is not home."""

from __future__ import annotations

import numpy as np
import pytest

import robofleet
from robofleet.avoidance.navigation.goal import GoalChecker

SIGMA, TOLERANCE = 0.1, 0.1


def test_home_needs_the_estimate_within_the_tolerance_while_holding():
    goals = np.zeros((3, 2))
    checker = GoalChecker.initial(3, TOLERANCE)
    checker.observe(np.array([[0.05, 0.0], [0.05, 0.0], [1.0, 0.0]]), goals)
    checker.settle(np.array([True, False, True]))  # robot 1 is stepping aside
    assert checker.arrived.tolist() == [True, True, False] and checker.home.tolist() == [True, False, False]
    checker.observe(np.array([[0.3, 0.0], [0.6, 0.0], [1.0, 0.0]]), goals)  # robot 1's return ran out: it holds away
    checker.settle(True)
    assert checker.home.tolist() == [True, False, False] and not checker.all_home()
    checker.observe(np.array([[0.0, 0.0], [0.02, 0.0], [0.0, 0.09]]), goals)
    checker.settle(True)
    assert checker.all_home()


def trap(seed: int):
    """Two robots parked across a corridor, a third must pass between them: the parked
    robots yield, and their returns run out of time after two steps."""
    mapping = {"family": "avoidance", "name": "trap", "method": "buavc", "max_steps": 500,
               "workspace": {"bounds": [-4, -1.4, 4, 1.4]},
               "robots": {"n": 3, "radius": 0.2, "v_max": 0.4, "sigma": SIGMA,
                          "layout": {"kind": "explicit", "starts": [[0, 0.475], [0, -0.475], [-3, 0]],
                                     "goals": [[0, 0.475], [0, -0.475], [3, 0]]}},
               "navigation": {"yielding": {"return_steps": 2}}}
    return robofleet.simulate(robofleet.load_scenario(mapping), seed=seed)


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_success_means_every_robot_is_home_when_returns_run_out(seed):
    out = trap(seed)
    final = np.linalg.norm(out.positions[-1] - np.asarray(out.metadata["goals"]), axis=1)
    assert out.results["max_true_goal_distance"] == pytest.approx(final.max())
    assert out.results["success"] and out.results["arrived"] == 1.0
    assert final.max() <= TOLERANCE + 4 * SIGMA  # the estimate within the tolerance, the truth within 4σ of it
