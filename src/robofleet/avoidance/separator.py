"""Best linear separator between two Gaussians (Zhu et al. 2022, appendix B).

For robots ``i`` and ``j`` with position estimates ``N(p̂_i, Σ_i)`` and ``N(p̂_j, Σ_j)``
the separator minimises the larger of the two misclassification probabilities
(Anderson & Bahadur 1962). With ``p̂_ij = p̂_j − p̂_i`` (appendix B, Eqs. 48–50):

* ``a(t) = [t Σ_i + (1 − t) Σ_j]⁻¹ p̂_ij``                         (48)
* ``b(t) = a(t)ᵀ p̂_i + t a(t)ᵀ Σ_i a(t)``                          (49)
* ``F(t) = a(t)ᵀ [t² Σ_i − (1 − t)² Σ_j] a(t) = 0``,  ``t ∈ (0, 1)`` (50)

then ``(a, b)`` is normalised so ``‖a‖ = 1``; robot ``i``'s side is ``aᵀ p ≤ b``.

Solver (ours, the authors' release uses a few Newton steps from 0.5 with a fallback):
``F(0⁺) < 0 < F(1⁻)`` whenever both covariances are positive definite, so a root is
bracketed; we run a vectorized Illinois (modified regula-falsi) iteration on the bracket,
which keeps the root bracketed and always converges, and stops per pair as soon as the
bracket or the residual is below tolerance. Equal covariances (the common case) give
``F(½) = 0`` exactly and finish in one evaluation. Singular covariances (``Σ = 0``, the
deterministic BVC) are handled by adding ``λ I`` with a tiny ``λ`` relative to the pair's
scale, which selects the limit of the formulas: for ``Σ_i = Σ_j = 0`` the perpendicular
bisector.

Scale: the plane does not change when ``p̂_ij`` or both covariances are multiplied by a
positive factor (``t`` solves a homogeneous equation, ``a`` only sets a direction, and
``b`` scales with ``a``). Every formula here therefore works on ``p̂_ij`` and ``Σ``
multiplied by powers of two that bring their largest entries into ``[½, 1)``
(:func:`power_of_two_scale`): exact in floating point (the result is bit for bit the
unscaled one whenever that one neither overflows nor underflows), and free of overflow and
underflow for estimates ``1e-300`` apart, ``1e20`` m away or covariances of ``1e300``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..core.errors import ConfigError, short_repr

_REG = 1e-12  # relative regularisation for singular covariances
_TOL_T = 1e-12
_MAX_ITER = 100


def gaussian_separator(mean_i: np.ndarray, cov_i: np.ndarray, mean_j: np.ndarray, cov_j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimax linear separator between ``N(mean_i, cov_i)`` and ``N(mean_j, cov_j)``.

    Parameters
    ----------
    mean_i, mean_j: arrays ``(..., d)``.
    cov_i, cov_j: arrays ``(..., d, d)``, symmetric positive semi-definite.
    All four broadcast against each other over the leading axes.

    Returns
    -------
    a: ``(..., d)`` unit normals pointing from ``i`` towards ``j``.
    b: ``(...)`` offsets; robot ``i``'s half-space is ``a·p ≤ b``.

    Raises
    ------
    ConfigError
        Naming the argument: not numbers, shapes that are not ``(..., d)`` / ``(..., d, d)``
        with one ``d`` or do not broadcast, NaN or infinite entries, covariances that are
        not symmetric positive semi-definite, or equal means (no separator exists).

    Notes
    -----
    Reciprocity: swapping the roles of ``i`` and ``j`` returns ``(−a, −b)`` (``t' = 1 − t``).
    Cost: O(K · iterations · d³) for K pairs, d ≤ 3; equal covariances take one iteration.
    """
    mean_i, mean_j = as_float_array(mean_i, "mean_i"), as_float_array(mean_j, "mean_j")
    cov_i, cov_j = as_float_array(cov_i, "cov_i"), as_float_array(cov_j, "cov_j")
    d = check_shapes(mean_i, cov_i, mean_j, cov_j)
    try:
        lead = np.broadcast_shapes(mean_i.shape[:-1], mean_j.shape[:-1], cov_i.shape[:-2], cov_j.shape[:-2])
    except ValueError:
        raise ConfigError(f"mean_i, cov_i, mean_j, cov_j: expected leading axes that broadcast, received shapes "
                          f"{mean_i.shape}, {cov_i.shape}, {mean_j.shape}, {cov_j.shape}") from None
    for name, cov in (("cov_i", cov_i), ("cov_j", cov_j)):
        check_covariance(cov, name)
    mi = np.broadcast_to(mean_i, lead + (d,)).reshape(-1, d)
    mj = np.broadcast_to(mean_j, lead + (d,)).reshape(-1, d)
    ci = np.broadcast_to(cov_i, lead + (d, d)).reshape(-1, d, d)
    cj = np.broadcast_to(cov_j, lead + (d, d)).reshape(-1, d, d)
    equal = np.flatnonzero(np.all(mi == mj, axis=1))
    if len(equal):
        raise ConfigError(f"mean_i, mean_j: expected distinct means (no separator exists between equal means), "
                          f"received equal means {mi[equal[0]].tolist()} at flat index {int(equal[0])}")
    a, b = separator_flat(mi, ci, mj, cj)
    return a.reshape(lead + (d,)), b.reshape(lead)


def as_float_array(value: object, name: str) -> np.ndarray:
    """``value`` as a finite float array, or a :class:`ConfigError` naming ``name`` (real
    numbers only: ``None``, booleans, complex numbers and text are refused)."""
    array, refused = _real_array(value)
    if array is None:
        raise ConfigError(f"{name}: expected an array of numbers (real ones), received {refused}{short_repr(value)}")
    if not np.all(np.isfinite(array)):
        raise ConfigError(f"{name}: expected finite numbers, received NaN or infinite entries ({short_repr(value)})")
    return array


def _real_array(value: object) -> tuple[np.ndarray | None, str]:
    """``(value as a float array, "")``, or ``(None, what it holds)`` when it is not real numbers."""
    try:
        kind = np.asarray(value).dtype.kind if value is not None else "O"
        if kind in "bc":
            return None, {"b": "booleans ", "c": "complex numbers "}[kind]
        if kind in "iufO" and value is not None:
            return np.asarray(value, dtype=float), ""
    except (TypeError, ValueError):
        pass
    return None, ""


def check_shapes(mean_i: np.ndarray, cov_i: np.ndarray, mean_j: np.ndarray, cov_j: np.ndarray) -> int:
    """The common dimension ``d`` of means ``(..., d)`` and covariances ``(..., d, d)``."""
    if mean_i.ndim < 1 or mean_j.ndim < 1 or mean_i.shape[-1] != mean_j.shape[-1] or mean_i.shape[-1] < 1:
        raise ConfigError(f"mean_i, mean_j: expected arrays (..., d) with the same d, received shapes {mean_i.shape} and {mean_j.shape}")
    d = mean_i.shape[-1]
    for name, cov in (("cov_i", cov_i), ("cov_j", cov_j)):
        if cov.ndim < 2 or cov.shape[-2:] != (d, d):
            raise ConfigError(f"{name}: expected an array (..., {d}, {d}) matching the means, received shape {cov.shape}")
    return d


def check_covariance(cov: np.ndarray, name: str) -> None:
    """Refuse covariances that are not symmetric positive semi-definite (relative tolerance)."""
    scale = max(float(np.abs(cov).max(initial=0.0)), 1e-300)
    if not np.allclose(cov, np.swapaxes(cov, -1, -2), rtol=0.0, atol=1e-9 * scale):
        raise ConfigError(f"{name}: expected symmetric covariance matrices, received {short_repr(cov.tolist())}")
    if np.linalg.eigvalsh(cov).min(initial=0.0) < -1e-9 * scale:
        raise ConfigError(f"{name}: expected positive semi-definite covariance matrices (eigenvalues ≥ 0), received {short_repr(cov.tolist())}")


def power_of_two_scale(values: np.ndarray, axes: tuple[int, ...]) -> np.ndarray:
    """Per leading index, the exponent ``e`` with ``max |values| · 2^-e ∈ [½, 1)`` over
    ``axes`` (0 where all are zero): multiplying by ``2^-e`` is exact."""
    return np.frexp(np.abs(values).max(axis=axes, initial=0.0))[1]


def scaled(values: np.ndarray, exponent: np.ndarray) -> np.ndarray:
    """``values · 2^-exponent`` with ``exponent`` broadcast over the trailing axes of ``values``."""
    return np.ldexp(values, -exponent.reshape(exponent.shape + (1,) * (values.ndim - exponent.ndim)))


def separator_flat(mi: np.ndarray, ci: np.ndarray, mj: np.ndarray, cj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gaussian_separator` on flat arrays ``(K, d)`` and ``(K, d, d)`` (no broadcasting).

    Works on ``p̂_ij · 2^-m`` and ``Σ · 2^-k`` (module docstring, "Scale"): with ``a'`` the
    normal of the scaled pair, ``a = 2^(m−k) a'`` and ``b = (a'ᵀp̂_i + 2^m t a'ᵀΣ'_i a') / ‖a'‖``."""
    m = power_of_two_scale(mj - mi, (1,))
    k = np.maximum(power_of_two_scale(ci, (1, 2)), power_of_two_scale(cj, (1, 2)))
    diff = scaled(mj - mi, m)
    ci, cj = _regularise(scaled(ci, k), scaled(cj, k))
    same = np.all((ci == cj).reshape(len(ci), ci.shape[-1] ** 2), axis=1)
    t = np.full(len(diff), 0.5)  # F(1/2) = 0 exactly when Σ_i = Σ_j
    differ = np.flatnonzero(~same)
    if len(differ):
        t[differ] = solve_t(diff[differ], ci[differ], cj[differ])
    a = _solve(t[:, None, None] * ci + (1.0 - t)[:, None, None] * cj, diff)
    b = np.einsum("kd,kd->k", a, mi) + np.ldexp(t * _quad(a, ci), m)
    norm = np.linalg.norm(a, axis=-1)
    return a / norm[:, None], b / norm


def shared_covariance_separator(mi: np.ndarray, mj: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed form of Eqs. (48)–(50) when every robot has the same ``cov`` (``(d, d)``).

    ``Σ_i = Σ_j = Σ`` gives ``F(½) = 0``, so ``a = Σ⁻¹(p̂_j − p̂_i)`` and
    ``b = aᵀ(p̂_i + p̂_j)/2`` (normalised). ``Σ = 0`` is the deterministic BVC limit
    ``a ∝ p̂_j − p̂_i``; a singular ``Σ ≠ 0`` is regularised as in :func:`separator_flat`.
    ``p̂_j − p̂_i`` and Σ are scaled by powers of two first (module docstring, "Scale").
    O(K d) for K pairs.
    """
    diff = scaled(mj - mi, power_of_two_scale(mj - mi, (1,)))
    if np.any(cov):
        unit = scaled(cov, power_of_two_scale(cov, (0, 1)))
        reg, _ = _regularise(unit[None], unit[None])
        a = np.linalg.solve(reg[0], diff.T).T
    else:
        a = diff
    norm = np.linalg.norm(a, axis=-1)
    b = np.einsum("kd,kd->k", a, 0.5 * (mi + mj))
    return a / norm[:, None], b / norm


SHARED_ZERO, SHARED_DIAGONAL, SHARED_DIVIDE, SHARED_GENERAL = 0, 1, 2, 3
"""How :func:`shared_separator_row` applies Σ⁻¹: Σ = 0 (BVC); diagonal, by the reciprocal
or by division; a full 2×2."""


def separator_mode(cov: np.ndarray, pairs: int = 2) -> tuple[int, np.ndarray]:
    """The shared 2×2 ``cov`` prepared for :func:`shared_separator_row`: ``(mode, solve)``
    with ``solve`` the diagonal or its reciprocal, or the regularised matrix flattened
    (regularised as :func:`separator_flat` does).

    A diagonal Σ is applied as :func:`shared_covariance_separator`'s LU solve rounds it:
    by the reciprocal of the diagonal for two or more right-hand sides, by division for
    ``pairs == 1`` (LAPACK's one-column path), so both forms give the same bits. Σ is
    scaled by a power of two first, as there (module docstring, "Scale")."""
    if not np.any(cov):
        return SHARED_ZERO, np.zeros(4)
    unit = scaled(cov, power_of_two_scale(cov, (0, 1)))
    reg = _regularise(unit[None], unit[None])[0][0]
    if reg[0, 1] == 0.0 and reg[1, 0] == 0.0:
        if pairs == 1:
            return SHARED_DIVIDE, np.array([reg[0, 0], reg[1, 1], 0.0, 0.0])
        return SHARED_DIAGONAL, np.array([1.0 / reg[0, 0], 1.0 / reg[1, 1], 0.0, 0.0])
    return SHARED_GENERAL, np.ascontiguousarray(reg, dtype=np.float64).reshape(4)


@numba.njit(cache=True, inline="always")
def shared_separator_row(xi, yi, xj, yj, mode, solve):
    """Robot i's unit normal and offset ``(a_x, a_y, b)`` for neighbour j under a shared Σ
    (:func:`shared_covariance_separator` for one pair, compiled).

    ``a = Σ⁻¹(p̂_j − p̂_i)`` — the reciprocal diagonal for a diagonal Σ, which is how the
    LU solve :func:`numpy.linalg.solve` of the vectorized form rounds too, else 2×2 LU with
    partial pivoting — then ``b = aᵀ(p̂_i + p̂_j)/2``, both divided by ``‖a‖``;
    ``p̂_j − p̂_i`` is first scaled by a power of two when its size is outside
    ``(1e-150, 1e150)`` (module docstring, "Scale"; exact, so the bits are those of the
    vectorized form, which always scales). Every
    operation is odd in ``p̂_j − p̂_i`` or symmetric in ``(i, j)``, so robot j's row for
    the same pair is exactly ``(−a, −b)`` (appendix B).
    """
    d0, d1 = xj - xi, yj - yi
    size = max(abs(d0), abs(d1))
    if not 1e-150 < size < 1e150:  # scale only where a square could leave the floating-point range (exact either way)
        exponent = math.frexp(size)[1]
        d0, d1 = math.ldexp(d0, -exponent), math.ldexp(d1, -exponent)
    if mode == SHARED_ZERO:
        a0, a1 = d0, d1
    elif mode == SHARED_DIAGONAL:
        a0, a1 = d0 * solve[0], d1 * solve[1]
    elif mode == SHARED_DIVIDE:
        a0, a1 = d0 / solve[0], d1 / solve[1]
    elif abs(solve[0]) >= abs(solve[2]):
        l = solve[2] / solve[0]
        a1 = (d1 - l * d0) / (solve[3] - l * solve[1])
        a0 = (d0 - solve[1] * a1) / solve[0]
    else:
        l = solve[0] / solve[2]
        a1 = (d0 - l * d1) / (solve[1] - l * solve[3])
        a0 = (d1 - solve[3] * a1) / solve[2]
    norm = np.sqrt(a0 * a0 + a1 * a1)
    off = a0 * (0.5 * (xi + xj)) + a1 * (0.5 * (yi + yj))
    return a0 / norm, a1 / norm, off / norm


def solve_t(diff: np.ndarray, ci: np.ndarray, cj: np.ndarray) -> np.ndarray:
    """Root ``t ∈ (0, 1)`` of Eq. (50) for every pair (Illinois iteration on the bracket);
    in the plane, :func:`solve_t_2d` (compiled, the same operations and bits)."""
    if diff.shape[-1] == 2:
        return solve_t_2d(np.ascontiguousarray(diff, dtype=np.float64), np.ascontiguousarray(ci, dtype=np.float64),
                          np.ascontiguousarray(cj, dtype=np.float64))
    return solve_t_vectorized(diff, ci, cj)


def solve_t_vectorized(diff: np.ndarray, ci: np.ndarray, cj: np.ndarray) -> np.ndarray:
    """:func:`solve_t` on all pairs at once, any dimension (numpy)."""
    k = len(diff)
    t = np.full(k, 0.5)
    f_mid = _residual(t, diff, ci, cj)
    todo = np.flatnonzero(np.abs(f_mid) > 1e-14 * (1.0 + _scale(diff, ci, cj)))
    if len(todo) == 0:
        return t
    lo, hi = np.zeros(len(todo)), np.ones(len(todo))
    f_lo = _residual(lo, diff[todo], ci[todo], cj[todo])
    f_hi = _residual(hi, diff[todo], ci[todo], cj[todo])
    idx = np.arange(len(todo))
    side = np.zeros(len(todo), dtype=np.int8)  # Illinois: which end was kept last time
    for _ in range(_MAX_ITER):
        if len(idx) == 0:
            break
        x = (lo[idx] * f_hi[idx] - hi[idx] * f_lo[idx]) / (f_hi[idx] - f_lo[idx])
        x = np.where(np.isfinite(x) & (x > lo[idx]) & (x < hi[idx]), x, 0.5 * (lo[idx] + hi[idx]))
        rows = todo[idx]
        fx = _residual(x, diff[rows], ci[rows], cj[rows])
        neg = fx < 0
        # replace the end with the same sign; halve the kept end's value if kept twice (Illinois)
        lo[idx] = np.where(neg, x, lo[idx])
        hi[idx] = np.where(neg, hi[idx], x)
        keep_hi, keep_lo = neg & (side[idx] == 1), ~neg & (side[idx] == -1)
        f_hi[idx] = np.where(neg, np.where(keep_hi, 0.5 * f_hi[idx], f_hi[idx]), fx)
        f_lo[idx] = np.where(neg, fx, np.where(keep_lo, 0.5 * f_lo[idx], f_lo[idx]))
        side[idx] = np.where(neg, 1, -1)
        t[rows] = x
        done = (hi[idx] - lo[idx] < _TOL_T) | (fx == 0)
        idx = idx[~done]
    return t


@numba.njit(cache=True, error_model="numpy")
def solve_t_2d(diff, ci, cj):
    """:func:`solve_t` for 2 × 2 covariances, pair by pair: every operation of the
    vectorized form (:func:`_residual`, :func:`_scale`, the Illinois update) in its order,
    so the roots are the same bits (a pair's iterations never depend on another pair)."""
    t = np.full(len(diff), 0.5)
    for r in range(len(diff)):
        f_mid = _residual_2d(0.5, diff[r], ci[r], cj[r])
        a0, a1 = _solve_2d(0.5 * (ci[r, 0, 0] + cj[r, 0, 0]), 0.5 * (ci[r, 0, 1] + cj[r, 0, 1]),
                           0.5 * (ci[r, 1, 0] + cj[r, 1, 0]), 0.5 * (ci[r, 1, 1] + cj[r, 1, 1]), diff[r, 0], diff[r, 1])
        if not abs(f_mid) > 1e-14 * (1.0 + (_quad_2d(a0, a1, ci[r]) + _quad_2d(a0, a1, cj[r]))):
            continue
        lo, hi = 0.0, 1.0
        f_lo, f_hi = _residual_2d(lo, diff[r], ci[r], cj[r]), _residual_2d(hi, diff[r], ci[r], cj[r])
        side = 0  # Illinois: which end was kept last time
        for _ in range(_MAX_ITER):
            x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            if not (math.isfinite(x) and x > lo and x < hi):
                x = 0.5 * (lo + hi)
            fx = _residual_2d(x, diff[r], ci[r], cj[r])
            if fx < 0:  # replace the end with the same sign; halve the kept end's value if kept twice
                lo = x
                if side == 1:
                    f_hi = 0.5 * f_hi
                f_lo, side = fx, 1
            else:
                hi = x
                if side == -1:
                    f_lo = 0.5 * f_lo
                f_hi, side = fx, -1
            t[r] = x
            if hi - lo < _TOL_T or fx == 0:
                break
    return t


@numba.njit(cache=True, error_model="numpy", inline="always")
def _residual_2d(t, diff, ci, cj):
    """:func:`_residual` of one pair."""
    s = 1.0 - t
    a0, a1 = _solve_2d(t * ci[0, 0] + s * cj[0, 0], t * ci[0, 1] + s * cj[0, 1], t * ci[1, 0] + s * cj[1, 0],
                       t * ci[1, 1] + s * cj[1, 1], diff[0], diff[1])
    return t * t * _quad_2d(a0, a1, ci) - s * s * _quad_2d(a0, a1, cj)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _solve_2d(m00, m01, m10, m11, v0, v1):
    """:func:`_solve` of one 2 × 2 system."""
    det = m00 * m11 - m01 * m10
    return (m11 * v0 - m01 * v1) / det, (m00 * v1 - m10 * v0) / det


@numba.njit(cache=True, error_model="numpy", inline="always")
def _quad_2d(a0, a1, cov):
    """:func:`_quad` of one vector."""
    return a0 * (cov[0, 0] * a0 + 2 * cov[0, 1] * a1) + cov[1, 1] * (a1 * a1)


def _residual(t, diff, ci, cj):
    """F(t) of Eq. (50)."""
    a = _solve(t[:, None, None] * ci + (1.0 - t)[:, None, None] * cj, diff)
    return t**2 * _quad(a, ci) - (1.0 - t) ** 2 * _quad(a, cj)


def _scale(diff, ci, cj):
    a = _solve(0.5 * (ci + cj), diff)
    return _quad(a, ci) + _quad(a, cj)


def _quad(a, cov):
    """``aᵀ Σ a`` per row."""
    if a.shape[-1] == 2:
        return a[:, 0] * (cov[:, 0, 0] * a[:, 0] + 2 * cov[:, 0, 1] * a[:, 1]) + cov[:, 1, 1] * a[:, 1] ** 2
    return np.einsum("ki,kij,kj->k", a, cov, a)


def _regularise(ci, cj):
    """Add ``λ I`` (λ tiny relative to the pair's covariance scale) where a matrix is singular."""
    d = ci.shape[-1]
    if _det(ci).min(initial=1.0) > 0 and _det(cj).min(initial=1.0) > 0:
        return ci, cj
    scale = np.maximum(np.trace(ci, axis1=1, axis2=2), np.trace(cj, axis1=1, axis2=2)) / d
    lam = np.where(scale > 0, scale * _REG, _REG)[:, None, None] * np.eye(d)
    return ci + lam, cj + lam


def _det(m: np.ndarray) -> np.ndarray:
    """Determinants of a stack of matrices (closed form for 2×2)."""
    if m.shape[-1] == 2:
        return m[:, 0, 0] * m[:, 1, 1] - m[:, 0, 1] * m[:, 1, 0]
    return np.linalg.det(m)


def _solve(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Solve ``m x = v`` for stacks of 2×2 (closed form) or d×d matrices."""
    if m.shape[-1] == 2:
        det = _det(m)
        x0 = (m[:, 1, 1] * v[:, 0] - m[:, 0, 1] * v[:, 1]) / det
        x1 = (m[:, 0, 0] * v[:, 1] - m[:, 1, 0] * v[:, 0]) / det
        return np.stack([x0, x1], axis=-1)
    return np.linalg.solve(m, v[..., None])[..., 0]
