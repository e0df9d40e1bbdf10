"""Appendix B: the minimax separator, its reciprocity and its special cases."""

import numpy as np
from hypothesis import given, settings, strategies as st
from scipy.special import ndtr

from robofleet.avoidance import gaussian_separator, separator


def random_cov(rng, n, lo=0.02, hi=0.5):
    angle = rng.uniform(0, np.pi, n)
    sd = rng.uniform(lo, hi, (n, 2))
    c, s = np.cos(angle), np.sin(angle)
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    return R @ (sd[:, :, None] ** 2 * np.eye(2)) @ R.transpose(0, 2, 1)


def margins(a, b, mi, ci, mj, cj):
    """u1, u2 of appendix B (standardised distances of each mean to the plane)."""
    si = np.sqrt(np.einsum("ki,kij,kj->k", a, ci, a))
    sj = np.sqrt(np.einsum("ki,kij,kj->k", a, cj, a))
    return (b - np.einsum("kd,kd->k", a, mi)) / si, (np.einsum("kd,kd->k", a, mj) - b) / sj


def test_separator_is_the_numerical_minimax():
    rng = np.random.default_rng(3)
    k = 40
    mi, mj = rng.normal(size=(k, 2)), rng.normal(size=(k, 2)) * 1.5
    ci, cj = random_cov(rng, k), random_cov(rng, k)
    a, b = gaussian_separator(mi, ci, mj, cj)
    u1, u2 = margins(a, b, mi, ci, mj, cj)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(u1, u2, atol=1e-6)  # equal misclassification probabilities
    # brute force: for a direction a the best b equalises the margins, giving
    # u(a) = aᵀ(m_j − m_i) / (√(aᵀΣ_i a) + √(aᵀΣ_j a)); maximise over a dense set of angles
    theta = np.linspace(0, 2 * np.pi, 200_001)
    dirs = np.stack([np.cos(theta), np.sin(theta)], 1)
    for n in range(k):
        num = dirs @ (mj[n] - mi[n])
        den = np.sqrt(np.einsum("ki,ij,kj->k", dirs, ci[n], dirs)) + np.sqrt(np.einsum("ki,ij,kj->k", dirs, cj[n], dirs))
        best = (num / den).max()
        assert u1[n] >= best - 1e-6
        assert u1[n] <= best + 1e-6


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(0.05, 5.0))
def test_reciprocity(seed, scale):
    rng = np.random.default_rng(seed)
    mi, mj = rng.normal(size=(8, 2)) * scale, rng.normal(size=(8, 2)) * scale
    ci, cj = random_cov(rng, 8), random_cov(rng, 8)
    a, b = gaussian_separator(mi, ci, mj, cj)
    a2, b2 = gaussian_separator(mj, cj, mi, ci)
    np.testing.assert_allclose(a2, -a, atol=1e-9)
    np.testing.assert_allclose(b2, -b, atol=1e-9 * (1 + scale))
    # each mean on its own side
    assert np.all(np.einsum("kd,kd->k", a, mi) < b)
    assert np.all(np.einsum("kd,kd->k", a, mj) > b)


def test_equal_isotropic_and_zero_covariances_give_the_bisector():
    rng = np.random.default_rng(0)
    mi, mj = rng.normal(size=(20, 2)), rng.normal(size=(20, 2))
    mid = 0.5 * (mi + mj)
    unit = (mj - mi) / np.linalg.norm(mj - mi, axis=1, keepdims=True)
    for cov in (0.3**2 * np.eye(2), np.zeros((2, 2))):
        a, b = gaussian_separator(mi, cov, mj, cov)
        np.testing.assert_allclose(a, unit, atol=1e-9)
        np.testing.assert_allclose(b, np.einsum("kd,kd->k", a, mid), atol=1e-9)


def test_broadcasting_over_leading_axes():
    rng = np.random.default_rng(1)
    mi = rng.normal(size=(3, 4, 2))
    mj = rng.normal(size=(4, 2)) + 3
    a, b = gaussian_separator(mi, 0.04 * np.eye(2), mj, random_cov(rng, 4))
    assert a.shape == (3, 4, 2) and b.shape == (3, 4)


def test_misclassification_probability_decreases_with_distance():
    """Sanity: further apart → smaller equal error probability."""
    cov = np.diag([0.1, 0.3]) ** 2
    errs = []
    for d in (0.5, 1.0, 2.0):
        a, b = gaussian_separator(np.zeros(2), cov, np.array([d, d]), cov.T)
        u1, _ = margins(a[None], np.array([b]), np.zeros((1, 2)), cov[None], np.array([[d, d]]), cov[None])
        errs.append(1 - ndtr(u1[0]))
    assert errs[0] > errs[1] > errs[2]


def test_shared_covariance_closed_form_equals_the_general_solver():
    from robofleet.avoidance.separator import shared_covariance_separator

    rng = np.random.default_rng(9)
    mi, mj = rng.normal(size=(50, 2)), rng.normal(size=(50, 2))
    for cov in (random_cov(rng, 1)[0], np.zeros((2, 2)), 0.01 * np.eye(2), np.diag([0.01, 0.0])):
        a, b = shared_covariance_separator(mi, mj, cov)
        a2, b2 = gaussian_separator(mi, cov, mj, cov)
        np.testing.assert_allclose(a, a2, atol=1e-9)
        np.testing.assert_allclose(b, b2, atol=1e-9)


def random_covariances(rng, count, scales):
    """``count`` random symmetric positive semi-definite 2 × 2 matrices of the given scales."""
    factors = rng.normal(size=(count, 2, 2)) * scales[:, None, None]
    return factors @ factors.transpose(0, 2, 1)


def test_the_compiled_root_of_eq_50_is_the_vectorized_one_bit_for_bit():
    """Pairs of any scale (10⁻⁶ to 10³), equal, singular and coincident ones: the compiled
    plane solver returns the same bits as the vectorized Illinois iteration."""
    rng = np.random.default_rng(50)
    with np.errstate(all="ignore"):
        for trial in range(600):
            count = int(rng.integers(1, 30))
            scales = 10.0 ** rng.uniform(-6, 3, count)
            diff = rng.normal(size=(count, 2)) * 10.0 ** rng.uniform(-3, 3, (count, 1))
            ci = random_covariances(rng, count, scales)
            cj = random_covariances(rng, count, scales * 10.0 ** rng.uniform(-2, 2, count))
            if trial % 7 == 0:
                cj[: count // 2] = ci[: count // 2]
            if trial % 11 == 0:
                ci[:, 1, :] = ci[:, :, 1] = 0.0
            if trial % 13 == 0:
                diff[0] = 0.0
            ci, cj = separator._regularise(ci, cj)
            np.testing.assert_array_equal(separator.solve_t_2d(diff, ci, cj), separator.solve_t_vectorized(diff, ci, cj),
                                          err_msg=str(trial))
