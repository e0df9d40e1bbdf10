"""The chance constraint holds in Monte Carlo (fixed seeds), and fails without buffers."""

import numpy as np
from shapely.geometry import Polygon

from robofleet.avoidance import CellGeometry, ObstacleSet, build_cells, confidence_quantile, shadow_epsilon
from robofleet.core import geometry

DELTA = 0.1
SAMPLES = 200_000


def two_robot_cells(cov_i, cov_j, quantile, radius=0.2):
    est = np.array([[0.0, 0.0], [1.6, 0.7]])
    covs = np.stack([cov_i, cov_j])
    geo = CellGeometry(ObstacleSet.build([], [], 0.0), np.zeros((0, 2)), np.zeros(0))
    return est, build_cells(est, covs, np.full(2, radius), quantile, geo, local_box=5.0)


def worst_case_means(est, cells):
    """Each robot's planned position pushed onto the boundary of its own cell."""
    a, b = cells.A[:, 0], cells.b[:, 0]
    return est + (b - np.einsum("nd,nd->n", a, est))[:, None] * a


def collision_rate(means, covs, radius, rng):
    pi = rng.multivariate_normal(means[0], covs[0], SAMPLES)
    pj = rng.multivariate_normal(means[1], covs[1], SAMPLES)
    return np.mean(np.linalg.norm(pi - pj, axis=1) < 2 * radius)


def test_pair_collision_probability_below_delta_even_at_the_cell_boundary():
    rng = np.random.default_rng(11)
    cov_i = np.array([[0.02, 0.008], [0.008, 0.01]])
    cov_j = np.array([[0.005, -0.002], [-0.002, 0.03]])
    est, cells = two_robot_cells(cov_i, cov_j, confidence_quantile(DELTA))
    means = worst_case_means(est, cells)
    # each robot leaves its side (shrunk by r_s) with probability exactly 1 − √(1 − δ)
    a, b = cells.A[0, 0], cells.b[0, 0] + cells.b[0, 0] * 0  # robot 0's plane (tightened)
    sep_b = b + (0.2 + confidence_quantile(DELTA) * np.sqrt(a @ cov_i @ a))  # untightened b
    side = rng.multivariate_normal(means[0], cov_i, SAMPLES) @ a > sep_b - 0.2
    expected = 1 - np.sqrt(1 - DELTA)
    assert abs(side.mean() - expected) < 4 * np.sqrt(expected * (1 - expected) / SAMPLES)
    rate = collision_rate(means, np.stack([cov_i, cov_j]), 0.2, rng)
    assert rate <= DELTA + 3 * np.sqrt(DELTA * (1 - DELTA) / SAMPLES)


def test_deterministic_bvc_violates_the_bound_under_noise():
    """The same Monte Carlo with BVC cells (no buffer for Σ) breaks δ: the test can fail."""
    rng = np.random.default_rng(12)
    cov = 0.1**2 * np.eye(2)
    est, cells = two_robot_cells(np.zeros((2, 2)), np.zeros((2, 2)), 0.0)
    means = worst_case_means(est, cells)
    assert collision_rate(means, np.stack([cov, cov]), 0.2, rng) > DELTA


def test_obstacle_collision_probability_below_delta():
    rng = np.random.default_rng(13)
    cov_r = np.array([[0.012, 0.003], [0.003, 0.008]])
    cov_o = np.array([[0.01, -0.004], [-0.004, 0.02]])
    box = geometry.box_vertices((0.0, 0.0), (1.0, 1.0), yaw=0.3)
    eps = shadow_epsilon(DELTA)
    obs = ObstacleSet.build([box], cov_o[None], eps)
    geo = CellGeometry(obs, np.zeros((0, 2)), np.zeros(0))
    for start in ([1.5, 0.2], [-0.9, -1.3], [0.1, 1.6]):
        est = np.array([start])
        cells = build_cells(est, cov_r[None], np.array([0.2]), confidence_quantile(DELTA), geo, local_box=5.0)
        a, b = cells.robot(0)
        mean = est[0] + (b[0] - a[0] @ est[0]) * a[0]  # on the boundary of the obstacle constraint
        p = rng.multivariate_normal(mean, cov_r, SAMPLES)
        d = rng.multivariate_normal(np.zeros(2), cov_o, SAMPLES)
        dist = geometry.polygon_distance(p - d, box)  # distance to the displaced obstacle
        rate = np.mean(dist < 0.2)
        assert rate <= DELTA + 3 * np.sqrt(DELTA * (1 - DELTA) / SAMPLES)


def test_shadow_plane_keeps_every_shadow_point_on_the_far_side():
    cov_o = np.array([[0.04, 0.01], [0.01, 0.02]])
    box = geometry.box_vertices((1.0, -0.5), (1.0, 0.6))
    eps = 0.05
    obs = ObstacleSet.build([box], cov_o[None], eps)
    from robofleet.avoidance import obstacle_planes

    pts = np.array([[3.0, 0.0], [-1.0, -1.0], [1.0, 2.0], [2.5, -2.5]])
    a, b = obstacle_planes(pts, obs, np.zeros(len(pts), int))
    # boundary of D_o = {d : dᵀΣ⁻¹d ≤ r²} with r² the χ²₂ quantile
    r = obs.shadow_radius[0]
    theta = np.linspace(0, 2 * np.pi, 721)
    L = np.linalg.cholesky(cov_o)
    ds = r * np.stack([np.cos(theta), np.sin(theta)], 1) @ L.T
    shadow = (box[:, None] + ds[None]).reshape(-1, 2)
    for k in range(len(pts)):
        assert np.all(shadow @ a[k] >= b[k] - 1e-9)  # the shadow is outside the robot's side
        assert pts[k] @ a[k] < b[k]  # the robot is inside
        # the plane touches the shadow (max margin, shifted): some shadow point is on it
        assert np.min(shadow @ a[k] - b[k]) < 1e-3
    assert Polygon(shadow).area > 0
