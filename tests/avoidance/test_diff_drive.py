"""Three-projection differential-drive controller (docs/theory/buavc.md "Controllers")."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robofleet.avoidance.cell3d import workspace_box_planes
from robofleet.avoidance.diff_drive import line_interval, project_onto_cell_line, three_projection_control
from robofleet.dynamics import unicycle as uni


def random_cells(rng, n, m):
    angles = rng.uniform(0, 2 * np.pi, (n, m))
    A = np.stack([np.cos(angles), np.sin(angles)], -1)
    return A, rng.uniform(0.2, 2.0, (n, m))


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000))
def test_cell_line_projection_matches_dense_search(seed):
    rng = np.random.default_rng(seed)
    n, m = 8, 6
    A, b = random_cells(rng, n, m)
    valid = rng.random((n, m)) > 0.2
    origins = rng.uniform(-0.1, 0.1, (n, 2))
    ang = rng.uniform(0, 2 * np.pi, n)
    dirs = np.stack([np.cos(ang), np.sin(ang)], -1)
    goals = rng.uniform(-4, 4, (n, 2))
    proj, ok = project_onto_cell_line(origins, dirs, goals, A, b, valid)
    s = np.linspace(-30, 30, 30_001)
    for i in range(n):
        pts = origins[i] + s[:, None] * dirs[i]
        inside = np.all((pts @ A[i].T <= b[i]) | ~valid[i], axis=1)
        assert ok[i] == inside.any()
        if ok[i]:
            best = pts[inside][np.argmin(np.linalg.norm(pts[inside] - goals[i], axis=1))]
            assert np.all((proj[i] @ A[i].T <= b[i] + 1e-9) | ~valid[i])
            assert np.linalg.norm(proj[i] - goals[i]) <= np.linalg.norm(best - goals[i]) + 1e-12
            assert np.linalg.norm(best - proj[i]) < 4e-3


def test_line_interval_reports_empty_intersection():
    A = np.array([[[1.0, 0.0]]])
    b = np.array([[-1.0]])  # x ≤ −1, line x = 0 parallel to it: empty
    lo, hi = line_interval(np.zeros((1, 2)), np.array([[0.0, 1.0]]), A, b, np.ones((1, 1), bool))
    assert lo[0] > hi[0]


@pytest.mark.parametrize("heading", np.linspace(-np.pi, np.pi, 9))
def test_controller_converges_to_the_goal_when_alone(heading):
    params = uni.UnicycleParams(v_max=0.8, omega_max=np.pi / 2)
    A, b = workspace_box_planes([-5, -5], [5, 5])
    A, b = A[None], b[None] - 0.2
    valid = np.ones((1, 4), bool)
    state = np.array([[-2.0, 1.0, heading]])
    goal = np.array([[3.0, -2.5]])
    for _ in range(400):
        u = three_projection_control(state, goal, A, b, valid, params, 0.1)
        assert abs(u[0, 0]) <= params.v_max and abs(u[0, 1]) <= params.omega_max
        state = uni.step(state, u, 0.1, params)
    assert np.linalg.norm(state[0, :2] - goal[0]) < 0.02


def test_controller_stops_at_the_cell_boundary_along_the_heading():
    """Goal beyond a wall straight ahead: the robot drives up to the wall and no further."""
    params = uni.UnicycleParams(v_max=0.8, omega_max=np.pi / 2)
    A = np.array([[[1.0, 0.0], [-1, 0], [0, 1], [0, -1]]])
    b = np.array([[1.0, 5, 5, 5]])
    state = np.array([[0.0, 0.0, 0.0]])
    goal = np.array([[4.0, 0.0]])
    xs = []
    for _ in range(100):
        state = uni.step(state, three_projection_control(state, goal, A, b, np.ones((1, 4), bool), params, 0.1), 0.1, params)
        xs.append(state[0, 0])
    assert max(xs) <= 1.0 + 1e-9
    assert xs[-1] > 0.99
