"""3-D B-UAVC geometry against brute force: separator, projection, box shadows."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize, nnls
from scipy.special import ndtr

from robofleet.avoidance.cell3d import box_axes, box_shadow_planes, closest_points_on_boxes, project_onto_polytope, shadow_radius, whitening, workspace_box_planes
from robofleet.avoidance.separator import gaussian_separator


def random_spd(rng, d=3):
    m = rng.normal(size=(d, d)) * 0.3
    return m @ m.T + 0.01 * np.eye(d)


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_3d_separator_is_the_minimax_plane(seed):
    rng = np.random.default_rng(seed)
    mi, mj = rng.normal(size=3), rng.normal(size=3) + np.array([2.0, 0, 0])
    ci, cj = random_spd(rng), random_spd(rng)
    a, b = gaussian_separator(mi, ci, mj, cj)
    assert np.isclose(np.linalg.norm(a), 1.0)

    def worst_error(x):
        d = x[:3] / np.linalg.norm(x[:3])
        return max(1 - ndtr((x[3] - d @ mi) / np.sqrt(d @ ci @ d)), 1 - ndtr((d @ mj - x[3]) / np.sqrt(d @ cj @ d)))

    ours = worst_error(np.append(a, b))
    best = min((minimize(worst_error, np.append(x0, x0 @ (mi + mj) / 2), method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-14, "maxiter": 4000}).fun
                for x0 in [mj - mi, rng.normal(size=3)]))
    assert ours <= best + 1e-7


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(4, 12))
def test_3d_projection_is_exact(seed, m):
    rng = np.random.default_rng(seed)
    n = 6
    A = rng.normal(size=(n, m, 3))
    A /= np.linalg.norm(A, axis=-1, keepdims=True)
    b = rng.uniform(0.2, 1.5, (n, m))
    valid = rng.random((n, m)) > 0.15
    g = rng.normal(size=(n, 3)) * 3
    x, ok = project_onto_polytope(g, A, b, valid)
    assert ok.all()  # every cell contains the origin
    for i in range(n):
        Ai, bi = A[i, valid[i]], b[i, valid[i]]
        assert np.all(Ai @ x[i] <= bi + 1e-9)
        # KKT certificate: g − x = Σ λ_k a_k over active constraints, λ ≥ 0
        active = np.abs(Ai @ x[i] - bi) < 1e-7
        if active.any():
            lam, resid = nnls(Ai[active].T, g[i] - x[i])
            assert resid < 1e-7
        else:
            np.testing.assert_allclose(x[i], g[i], atol=1e-9)
        r = minimize(lambda y: np.sum((y - g[i]) ** 2), np.zeros(3), constraints=[{"type": "ineq", "fun": lambda y: bi - Ai @ y}], method="SLSQP", options={"ftol": 1e-14})
        assert np.sum((x[i] - g[i]) ** 2) <= r.fun + 1e-7


def test_projection_reports_empty_cells():
    A = np.array([[[1.0, 0, 0], [-1.0, 0, 0]]])
    b = np.array([[-1.0, -1.0]])  # x ≤ −1 and x ≥ 1
    _, ok = project_onto_polytope(np.zeros((1, 3)), A, b)
    assert not ok[0]


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_closest_point_on_yawed_box_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    centre = rng.normal(size=(1, 3))
    axes = box_axes(rng.uniform(0.2, 2.0, (1, 3)), rng.uniform(-np.pi, np.pi, 1))
    axes = np.einsum("ij,ojk->oik", whitening(random_spd(rng)), axes)  # a whitened (sheared) box
    pts = rng.normal(size=(5, 3)) * 3
    cp = closest_points_on_boxes(pts, centre, axes)[:, 0]
    for k in range(5):
        def squared_distance(z):  # and its gradient
            gap = centre[0] + axes[0] @ z - pts[k]
            return np.sum(gap**2), 2 * axes[0].T @ gap

        r = minimize(squared_distance, np.zeros(3), jac=True, bounds=[(-1, 1)] * 3, method="L-BFGS-B",
                     options={"ftol": 1e-15, "gtol": 1e-12})
        assert np.linalg.norm(cp[k] - pts[k]) <= np.sqrt(r.fun) + 1e-6


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_box_shadow_plane_separates_and_touches_the_shadow(seed):
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-2, 2, (2, 3))
    sizes = rng.uniform(0.3, 1.5, (2, 3))
    yaws = rng.uniform(-np.pi, np.pi, 2)
    cov = np.stack([random_spd(rng) * 0.05, np.zeros((3, 3))])
    eps = 0.05
    pts = rng.uniform(-6, 6, (6, 3))
    a, b = box_shadow_planes(pts, centers, sizes, yaws, cov, eps)
    np.testing.assert_allclose(np.linalg.norm(a, axis=-1), 1.0)
    z = rng.uniform(-1, 1, (4000, 3))
    z[:, rng.integers(0, 3, 4000)] = np.sign(z[:, 0:1])  # many surface points too
    for o in range(2):
        W = whitening(cov[o])
        r = 0.0 if o == 1 else shadow_radius(eps, 3)
        box_pts = centers[o] + z @ box_axes(sizes[o:o + 1], yaws[o:o + 1])[0].T
        u = rng.normal(size=(4000, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        shadow_pts = np.linalg.solve(W, (box_pts @ W.T + r * u).T).T  # grown in whitened space, mapped back
        for i in range(len(pts)):
            q = W @ pts[i]
            inside = np.all(np.abs(np.linalg.solve(W @ box_axes(sizes[o:o + 1], yaws[o:o + 1])[0], q - W @ centers[o])) <= 1)
            if inside:
                continue
            assert np.all(shadow_pts @ a[i, o] >= b[i, o] - 1e-9)  # the whole shadow is on the far side
            # the plane is the max-margin one: its whitened distance to q is dist(q, box) − r
            cp = closest_points_on_boxes(q[None], (W @ centers[o])[None], (W @ box_axes(sizes[o:o + 1], yaws[o:o + 1])[0])[None])[0, 0]
            wa = np.linalg.solve(W, a[i, o])  # plane in whitened coordinates: (W⁻¹a)·x ≤ b
            margin = (b[i, o] - wa @ q) / np.linalg.norm(wa)
            assert np.isclose(margin, np.linalg.norm(cp - q) - r, atol=1e-7)


def test_workspace_box_planes_include_height():
    A, b = workspace_box_planes([-5, -5, 0], [5, 5, 3])
    inside = np.array([[0, 0, 1.5], [4.9, -4.9, 0.1]])
    above = np.array([[0, 0, 3.1]])
    assert np.all(inside @ A.T <= b) and not np.all(above @ A.T <= b)
