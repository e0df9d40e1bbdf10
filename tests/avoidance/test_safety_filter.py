"""B-UAVC as a safety filter: the closest safe velocity, its premise cases, the per-robot
view against the batch, the deadlock memory, the per-step bound in Monte Carlo, bad input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize

from robofleet import load_scenario
from robofleet.avoidance import RobotSafetyFilter, SafetyFilter
from robofleet.avoidance.navigation.progress import DeadlockParams
from robofleet.core.errors import ConfigError, RobofleetError

ROOT = Path(__file__).resolve().parents[2]
BOXES = [np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]) + c for c in ([-2.0, 1.0], [2.0, -1.5])]


def fleet_filter(n, **kw):
    options = {"radius": 0.2, "dt": 0.1, "v_max": 0.4, "delta": 0.1, "bounds": (-4, -4, 4, 4), "obstacles": BOXES,
               "obstacle_cov": 0.05**2 * np.eye(2), "local_box": 2.0} | kw
    return SafetyFilter.create(n, **options)


def random_fleet(rng, n, spread=3.0):
    p = rng.uniform(-spread, spread, (n, 2))
    cov = np.array([np.diag(rng.uniform(0.02, 0.1, 2) ** 2) for _ in range(n)])
    return p, cov, rng.uniform(-0.6, 0.6, (n, 2))


def closest_safe_velocity(p, A, b, wanted, dt):
    """Brute-force reference: min ‖u − wanted‖ s.t. A (p + u Δt) ≤ b (SLSQP from many starts)."""
    cons = {"type": "ineq", "fun": lambda u: b - A @ (p + u * dt), "jac": lambda u: -A * dt}
    best = None
    for start in (wanted, np.zeros(2)):
        res = minimize(lambda u: np.sum((u - wanted) ** 2), start, jac=lambda u: 2 * (u - wanted), constraints=[cons],
                       method="SLSQP", options={"ftol": 1e-14, "maxiter": 200})
        if np.all(A @ (p + res.x * dt) <= b + 1e-7) and (best is None or res.fun < best.fun):
            best = res
    return best.x


def test_velocity_is_the_closest_one_keeping_the_next_estimate_in_the_cell():
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(8):
        f = fleet_filter(8)
        p, cov, desired = random_fleet(rng, 8)
        r = f.filter(p, cov, desired)
        for i in np.flatnonzero(r.estimate_in_cell & ~r.empty):
            A, b = r.cells.robot(i)
            u = r.velocity[i]
            assert np.all(A @ (p[i] + u * f.dt) <= b + 1e-9)
            assert np.linalg.norm(u) <= f.v_max[i] + 1e-12
            wanted = r.desired[i]
            reference = closest_safe_velocity(p[i], A, b, wanted, f.dt)
            assert np.linalg.norm(u - wanted) <= np.linalg.norm(reference - wanted) + 1e-6
            checked += 1
    assert checked > 30


def test_a_safe_desired_velocity_passes_unchanged_and_fast_ones_are_limited():
    f = fleet_filter(2, obstacles=[])
    p = np.array([[-2.0, 0.0], [2.0, 0.0]])
    r = f.filter(p, 0.01 * np.eye(2), np.array([[0.0, 0.3], [0.1, -0.2]]))
    assert np.array_equal(r.velocity, [[0.0, 0.3], [0.1, -0.2]]) and not r.modified.any()
    fast = f.filter(p, 0.01 * np.eye(2), np.array([[0.0, 3.0], [0.0, 0.0]]))
    assert np.allclose(fast.velocity[0], [0.0, 0.4]) and fast.modified[0] and not fast.modified[1]


def test_head_on_robots_are_slowed_before_their_cells_meet():
    f = fleet_filter(2, obstacles=[])
    p = np.array([[-0.3, 0.0], [0.3, 0.0]])
    r = f.filter(p, 0.05**2 * np.eye(2), np.array([[0.4, 0.0], [-0.4, 0.0]]))
    assert r.modified.all() and r.estimate_in_cell.all()
    assert np.all(np.abs(r.velocity[:, 0]) < 0.4) and r.velocity[0, 0] >= 0 >= r.velocity[1, 0]
    gap = (p[1] + r.velocity[1] * f.dt) - (p[0] + r.velocity[0] * f.dt)
    assert gap[0] >= 2 * 0.2 - 1e-9


def test_an_estimate_outside_its_cell_heads_back_at_most_v_max():
    f = fleet_filter(2, obstacles=[])
    p = np.array([[-0.1, 0.0], [0.1, 0.0]])  # closer than the buffers: both estimates outside
    r = f.filter(p, 0.05**2 * np.eye(2), np.zeros((2, 2)))
    assert not r.estimate_in_cell.any() and not r.empty.any()
    assert np.allclose(np.linalg.norm(r.velocity, axis=1), 0.4) and r.velocity[0, 0] < 0 < r.velocity[1, 0]
    for i in range(2):
        A, b = r.cells.robot(i)
        before, after = np.max(A @ p[i] - b), np.max(A @ (p[i] + r.velocity[i] * f.dt) - b)
        assert after < before


def test_an_empty_cell_holds_still():
    f = SafetyFilter.create(2, radius=0.55, dt=0.1, v_max=0.4, bounds=(-1, -1, 1, 1))
    r = f.filter(np.array([[-0.1, 0.0], [0.1, 0.0]]), np.zeros((2, 2)), np.array([[0.3, 0.1], [-0.2, 0.0]]))
    assert r.empty.all() and np.array_equal(r.velocity, np.zeros((2, 2)))


def test_each_robot_alone_gets_the_velocity_the_batch_computes_for_it():
    rng = np.random.default_rng(4)
    for _ in range(6):
        n = 12
        batch = fleet_filter(n)
        p, cov, desired = random_fleet(rng, n)
        offsets = rng.normal(0, 0.05, (2, 2))
        r = batch.filter(p, cov, desired, obstacle_offsets=offsets)
        for i in range(n):
            robot = RobotSafetyFilter.create(radius=0.2, dt=0.1, v_max=0.4, delta=0.1, bounds=(-4, -4, 4, 4), obstacles=BOXES,
                                             obstacle_cov=0.05**2 * np.eye(2), local_box=2.0, deadlock=None)
            others = np.delete(np.arange(n), i)
            mine = robot.filter(p[i], cov[i], desired[i], p[others], cov[others], obstacle_offsets=offsets)
            assert np.allclose(mine.velocity[0], r.velocity[i], atol=1e-9)
            assert mine.estimate_in_cell[0] == r.estimate_in_cell[i] and mine.empty[0] == r.empty[i]


def test_filters_built_from_a_scenario_agree():
    spec = load_scenario("avoidance/three_boxes")
    batch = SafetyFilter.from_spec(spec)
    rng = np.random.default_rng(0)
    p = rng.uniform(-4, 4, (5, 2))
    r = batch.filter(p, batch.covariances, rng.uniform(-0.4, 0.4, (5, 2)))
    for i in range(5):
        robot = RobotSafetyFilter.from_spec(spec, i, deadlock=None)
        mine = robot.filter(p[i], batch.covariances[i], r.desired[i], np.delete(p, i, 0))
        assert np.allclose(mine.velocity[0], r.velocity[i], atol=1e-9)


def test_the_per_step_bound_holds_in_monte_carlo():
    """Two robots pushed at each other: filtered, their next positions drawn from
    N(p̂ + uΔt, Σ) collide with probability at most δ (Sec. 4); unfiltered, far more often."""
    delta, dt = 0.1, 0.5
    f = SafetyFilter.create(2, radius=0.2, dt=dt, v_max=0.4, delta=delta)
    p = np.array([[-0.4, 0.02], [0.4, -0.02]])
    cov = np.array([0.08**2 * np.eye(2), np.diag([0.05, 0.1]) ** 2])
    push = np.array([[0.4, 0.0], [-0.4, 0.0]])
    r = f.filter(p, cov, push)
    assert r.estimate_in_cell.all() and r.modified.all()
    rng = np.random.default_rng(7)

    def collision_rate(u):
        nxt = [rng.multivariate_normal(p[i] + u[i] * dt, cov[i], 40_000) for i in range(2)]
        return np.mean(np.linalg.norm(nxt[0] - nxt[1], axis=1) < 0.4)

    assert collision_rate(r.velocity) <= delta
    assert collision_rate(push) > 0.3


def test_the_deadlock_memory_rotates_the_desired_velocity_after_sitting_still():
    params = DeadlockParams(window=5, recover_steps=3)
    robot = RobotSafetyFilter.create(radius=0.2, dt=0.1, v_max=0.4, bounds=(-2, -2, 2, 2), deadlock=params)
    p = np.array([1.8, 0.0])  # on its wall constraint x ≤ 2 − r_s, pushing straight into it
    first = robot.filter(p, np.zeros((2, 2)), [0.4, 0.0])
    assert first.deadlocked[0] and np.allclose(first.velocity, 0.0, atol=1e-9)
    rotated = [robot.filter(p, np.zeros((2, 2)), [0.4, 0.0]) for _ in range(3)]
    assert all(r.recovering[0] for r in rotated)
    assert np.allclose(rotated[0].desired[0], [0.0, -0.4]) and np.allclose(rotated[0].velocity[0], [0.0, -0.4])
    assert not robot.filter(p, np.zeros((2, 2)), [0.4, 0.0]).recovering[0]
    robot.reset()
    assert robot.memory.deadlocks[0] == 0


def test_the_batch_filter_is_stateless_unless_given_a_deadlock_memory():
    rng = np.random.default_rng(2)
    p, cov, desired = random_fleet(rng, 6)
    f = fleet_filter(6)
    a, b = f.filter(p, cov, desired), f.filter(p, cov, desired)
    assert np.array_equal(a.velocity, b.velocity) and f.memory is None
    assert fleet_filter(6, deadlock=DeadlockParams()).memory is not None


@pytest.mark.parametrize("call, where", [
    (lambda f: f.filter(np.full((3, 2), np.nan), np.eye(2), np.zeros((3, 2))), "estimates"),
    (lambda f: f.filter(np.zeros((2, 2)), np.eye(2), np.zeros((3, 2))), "estimates"),
    (lambda f: f.filter(np.eye(3)[:, :2], np.array([[1.0, 2.0], [2.0, 1.0]]), np.zeros((3, 2))), "covs"),
    (lambda f: f.filter(np.eye(3)[:, :2], np.eye(2), np.zeros((3, 3))), "desired"),
    (lambda f: f.filter(np.eye(3)[:, :2], np.eye(2), np.zeros((3, 2)), obstacle_offsets=np.zeros((5, 2))), "obstacle_offsets"),
    (lambda f: f.filter(np.zeros((3, 2)), np.eye(2), np.zeros((3, 2))), "estimates"),
    (lambda f: SafetyFilter.create(3, radius=-1, dt=0.1, v_max=0.4), "radius"),
    (lambda f: SafetyFilter.create(3, radius=0.2, dt=0.0, v_max=0.4), "dt"),
    (lambda f: SafetyFilter.create(3, radius=0.2, dt=0.1, v_max=[0.4, 0.4]), "v_max"),
    (lambda f: SafetyFilter.create(3, radius=0.2, dt=0.1, v_max=0.4, delta=1.5), "delta"),
    (lambda f: SafetyFilter.create(3, radius=0.2, dt=0.1, v_max=0.4, bounds=(1, 1, 0, 0)), "bounds"),
    (lambda f: SafetyFilter.create(3, radius=0.2, dt=0.1, v_max=0.4, obstacles=[[[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]]]), "obstacles[0]"),
    (lambda f: SafetyFilter.create(0, radius=0.2, dt=0.1, v_max=0.4), "n"),
    (lambda f: RobotSafetyFilter.create(radius=0.2, dt=0.1, v_max=0.4).filter([0, 0, 0], np.eye(2), [0, 0]), "estimate"),
    (lambda f: SafetyFilter.from_spec(load_scenario("avoidance/double_integrator")), "scenario"),
])
def test_bad_input_is_a_one_line_error_naming_the_argument(call, where):
    f = fleet_filter(3)
    with pytest.raises(RobofleetError) as info:
        call(f)
    assert isinstance(info.value, ConfigError)
    message = str(info.value)
    assert message.startswith(where + ":") and "expected" in message and "\n" not in message


def test_the_go_to_goal_example_runs():
    out = subprocess.run([sys.executable, str(ROOT / "examples" / "safety_filter_go_to_goal.py"), "--steps", "60"],
                         capture_output=True, text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "filtered" in out.stdout and "unfiltered" in out.stdout
