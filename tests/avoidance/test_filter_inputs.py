"""The safety filters at numeric extremes (finite velocities, no warnings, a fast desired
velocity keeps its direction at v_max) and misused (a one-line error naming the argument,
what was expected and what was received)."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.avoidance import RobotSafetyFilter, SafetyFilter
from robofleet.avoidance.navigation.progress import DeadlockParams
from robofleet.core.errors import ConfigError

pytestmark = pytest.mark.filterwarnings("error")  # numpy must not warn (overflow, invalid values, complex casts)
BOX = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) + 3.0
THREE = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
STILL = np.zeros((3, 2))


def fleet(**kw):
    options = {"radius": 0.2, "dt": 0.1, "v_max": 0.4, "bounds": (-5, -5, 5, 5), "obstacles": [BOX], "obstacle_cov": 0.01 * np.eye(2)} | kw
    return SafetyFilter.create(3, **options)


def robot(**kw):
    options = {"radius": 0.2, "dt": 0.1, "v_max": 0.4, "bounds": (-5, -5, 5, 5), "obstacles": [BOX]} | kw
    return RobotSafetyFilter.create(**options)


# ---------------------------------------------------------------------------------------
# numeric extremes
# ---------------------------------------------------------------------------------------
EXTREMES = {
    "estimates 1e-300 apart": lambda: fleet().filter(np.array([[0, 0], [1e-300, 0], [0, 1.0]]), 0.01 * np.eye(2), STILL),
    "estimates 1e-300 apart, Σ = 0": lambda: fleet().filter(np.array([[0, 0], [0, 1e-300], [1, 1.0]]), np.zeros((2, 2)), STILL),
    "estimates 1e-300 apart, own Σ": lambda: fleet().filter(np.array([[0, 0], [1e-300, 1e-300], [0, 1.0]]),
                                                           np.array([0.01 * np.eye(2), np.diag([0.02, 0.001]), np.zeros((2, 2))]), STILL),
    "one estimate 1e20 m away": lambda: fleet().filter(np.array([[0, 0], [1e20, -1e20], [0, 1.0]]), 0.01 * np.eye(2), STILL + 0.3),
    "a fleet 1e20 m away": lambda: fleet(bounds=None, obstacles=[]).filter(THREE * 1e5 + 1e20, 0.01 * np.eye(2), STILL + 0.3),
    "covariance 1e300": lambda: fleet().filter(THREE, 1e300 * np.eye(2), STILL + 0.3),
    "covariances 1e300 and 0.01": lambda: fleet(bounds=None).filter(THREE, np.array([1e300 * np.eye(2), 0.01 * np.eye(2), np.diag([1e300, 1e-300])]), STILL),
    "covariance 1e-300": lambda: fleet().filter(THREE, 1e-300 * np.eye(2), STILL + 0.3),
    "obstacle covariance 1e300": lambda: fleet(obstacle_cov=1e300 * np.eye(2)).filter(THREE, 0.01 * np.eye(2), STILL + 0.3),
    "a step of 1e99 m": lambda: fleet(v_max=1e49, dt=1e50).filter(THREE, 0.01 * np.eye(2), np.array([[1e300, 1.0], [0.3, 0.3], [-1e10, 1e10]])),
    "a robot's neighbour 1e-300 away": lambda: robot().filter([0, 0], 0.01 * np.eye(2), [0.3, 0], [[1e-300, 0.0]]),
    "a robot's covariance 1e300": lambda: robot().filter([0, 0], 1e300 * np.eye(2), [0.3, 0], [[1.0, 0.0]], 0.01 * np.eye(2)),
    "a robot 1e20 m from its neighbour": lambda: robot(bounds=None).filter([0, 0], 0.01 * np.eye(2), [0.3, 0], [[1e20, 0.0]]),
}


@pytest.mark.parametrize("case", list(EXTREMES))
def test_extreme_numbers_give_finite_bounded_velocities(case):
    result = EXTREMES[case]()
    assert np.all(np.isfinite(result.velocity)) and np.all(np.isfinite(result.desired))
    speed = np.hypot(result.velocity[:, 0], result.velocity[:, 1])
    assert np.all(speed <= np.max([0.4, 1e49]) * (1 + 1e-12))


@pytest.mark.parametrize("desired", [[1e200, 1e200], [-1e200, 3e199], [0.0, -1e308], [1e308, -1e308], [1e-300, 0.0]])
def test_a_desired_velocity_of_any_size_keeps_its_direction_at_v_max(desired):
    desired = np.array(desired)
    limited = desired if np.linalg.norm(desired / 1e300) * 1e300 <= 0.4 else None
    open_space = SafetyFilter.create(1, radius=0.2, dt=0.1, v_max=0.4).filter(np.zeros((1, 2)), 0.01 * np.eye(2), desired[None])
    alone = RobotSafetyFilter.create(radius=0.2, dt=0.1, v_max=0.4).filter([0.0, 0.0], 0.01 * np.eye(2), desired)
    for velocity in (open_space.velocity[0], alone.velocity[0]):
        if limited is not None:
            assert np.array_equal(velocity, limited)
            continue
        direction = desired / np.abs(desired).max()
        np.testing.assert_allclose(velocity, 0.4 * direction / np.linalg.norm(direction), rtol=1e-12)
    assert open_space.modified[0] == (limited is None)


# ---------------------------------------------------------------------------------------
# misuse: one line naming the argument
# ---------------------------------------------------------------------------------------
MISUSE = [
    # wrong argument types
    (lambda: fleet(obstacles=5), "obstacles"),
    (lambda: fleet(obstacles="box"), "obstacles"),
    (lambda: fleet(obstacles=[5]), "obstacles[0]"),
    (lambda: fleet(deadlock="yes"), "deadlock"),
    (lambda: fleet(deadlock=True), "deadlock"),
    (lambda: robot(deadlock="yes"), "deadlock"),
    (lambda: fleet(deadlock=DeadlockParams(window=0)), "deadlock.window"),
    (lambda: fleet(deadlock=DeadlockParams(progress_fraction=1.5)), "deadlock.progress_fraction"),
    (lambda: fleet(deadlock=DeadlockParams(enabled="no")), "deadlock.enabled"),
    (lambda: fleet(radius=True), "radius"),
    (lambda: fleet(dt="0.1"), "dt"),
    (lambda: fleet(local_box=None), "local_box"),
    (lambda: robot(v_max=[0.4, 0.5]), "v_max"),
    # complex arrays
    (lambda: fleet().filter(THREE + 0j, 0.01 * np.eye(2), STILL), "estimates"),
    (lambda: fleet().filter([[1j, 0], [1, 0], [0, 1]], 0.01 * np.eye(2), STILL), "estimates"),
    (lambda: fleet().filter(THREE, 0.01 * np.eye(2) + 0j, STILL), "covs"),
    (lambda: fleet().filter(THREE, 0.01 * np.eye(2), STILL + 1j), "desired"),
    (lambda: fleet().filter(THREE, 0.01 * np.eye(2), STILL, obstacle_offsets=np.zeros((1, 2)) + 0j), "obstacle_offsets"),
    (lambda: fleet(radius=0.2 + 0j), "radius"),
    (lambda: fleet(bounds=np.array([-5, -5, 5, 5]) + 0j), "bounds"),
    (lambda: fleet(obstacle_cov=np.eye(2) * (0.01 + 0j)), "obstacle_cov"),
    (lambda: fleet(obstacles=[BOX + 0j]), "obstacles[0]"),
    (lambda: robot().filter([0j, 0], np.eye(2), [0, 0]), "estimate"),
    (lambda: robot().filter([0, 0], np.eye(2), [0, 0], [[1, 0]], neighbour_radii=[0.3 + 0j]), "neighbour_radii"),
    # wrong shapes
    (lambda: fleet().filter(np.zeros((3, 3)), 0.01 * np.eye(2), STILL), "estimates"),
    (lambda: fleet().filter(THREE, 0.01 * np.eye(3), STILL), "covs"),
    (lambda: fleet().filter(THREE, np.zeros((2, 2, 2)), STILL), "covs"),
    (lambda: fleet().filter(THREE, 0.01 * np.eye(2), STILL[:2]), "desired"),
    (lambda: fleet(radius=[0.2, 0.3]), "radius"),
    (lambda: robot().filter([0, 0], np.eye(2), [0, 0], [[1, 0], [2, 0]], neighbour_radii=[0.3, 0.2, 0.1]), "neighbour_radii"),
    (lambda: robot().filter([0, 0], np.eye(2), [0, 0], [1, 2]), "neighbour_estimates"),
    (lambda: robot().filter([0, 0], np.eye(2), [0, 0], None), "neighbour_estimates"),
    # degenerate or out-of-range bounds and polygons
    (lambda: fleet(bounds=(0, 0, 0, 0)), "bounds"),
    (lambda: fleet(bounds=(1, 0, 0, 1)), "bounds"),
    (lambda: fleet(bounds=(0, 0, 1, np.nan)), "bounds"),
    (lambda: fleet(bounds=(0, 0, 1)), "bounds"),
    (lambda: fleet(bounds="box"), "bounds"),
    (lambda: fleet(bounds=[[0, 0], [1, 0], [2, 0]]), "bounds"),
    (lambda: fleet(bounds=[[0, 0], [1, 0], [1, 0], [1, 1], [0, 1]]), "bounds"),
    (lambda: fleet(bounds=[[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]]), "bounds"),
    (lambda: fleet(bounds=(0, 0, 1e-300, 1e-300)), "bounds"),
    (lambda: fleet(bounds=(-0.1, -0.1, 0.1, 0.1)), "bounds"),
    (lambda: fleet(radius=[0.2, 0.2, 1.5], bounds=(0, 0, 2, 2)), "bounds"),
    (lambda: fleet(bounds=(-1e308, -1e308, 1e308, 1e308)), "bounds"),
    (lambda: fleet(obstacles=[[[0, 0], [1, 0], [2, 0]]]), "obstacles[0]"),
    (lambda: fleet(obstacles=[[[0, 0], [1, 0], [1, 0], [0, 1]]]), "obstacles[0]"),
    (lambda: fleet(obstacles=[[[0, 0], [1, 0]]]), "obstacles[0]"),
    (lambda: fleet(obstacles=[np.zeros((0, 2))]), "obstacles[0]"),
    (lambda: fleet(obstacles=None), "obstacles"),
    (lambda: fleet(bounds=np.zeros((0, 2))), "bounds"),
    (lambda: fleet(obstacles=[[[0, 0], [1e300, 0], [0, 1e300]]]), "obstacles[0]"),
    # numbers out of range
    (lambda: fleet(radius=1e300), "radius"),
    (lambda: fleet(v_max=1e300), "v_max"),
    (lambda: fleet(v_max=1e3, dt=1e98), "v_max"),
    (lambda: fleet().filter(THREE * 1e200, 0.01 * np.eye(2), STILL), "estimates"),
    (lambda: fleet().filter(THREE, 1e308 * np.eye(2), STILL), "covs"),
    (lambda: fleet(obstacle_cov=1e308 * np.eye(2)), "obstacle_cov"),
]


@pytest.mark.parametrize("call, where", MISUSE)
def test_misuse_is_a_one_line_error_naming_the_argument(call, where):
    with pytest.raises(ConfigError) as info:
        call()
    message = str(info.value)
    assert message.startswith(where + ":") or message.startswith(where + ","), message
    assert "expected" in message and "received" in message and "\n" not in message
