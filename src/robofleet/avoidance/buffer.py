"""Chance-constrained buffers of the B-UAVC (Zhu et al. 2022; docs/theory/buavc.md "Buffer").

``β = r + Φ⁻¹(√(1 − δ)) · √(aᵀ Σ_i a)`` with ``‖a‖ = 1``, ``Σ_i`` the ego covariance and
``r`` the radius the row keeps: the pair's mean radius ``(r_i + r_j)/2`` for a neighbour,
the robot's own ``r_i`` for an obstacle or a wall (:mod:`.cell`). Robot ``i`` then stays on
its side of the separator, at least ``r`` from it, with probability ``≥ √(1 − δ)``; robot
``j`` likewise with its own ``Σ_j``; independence gives ``≥ 1 − δ`` for the pair, and the
slab of width ``r_i + r_j`` separates the two discs.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import ConfigError, short_repr


def confidence_quantile(delta: float) -> float:
    """``Φ⁻¹(√(1 − δ))``; e.g. 1.632 for δ = 0.10, 2.575 for δ = 0.01."""
    from scipy.special import ndtri  # imported on use: scenario files are read without scipy

    return float(ndtri(np.sqrt(1.0 - checked_delta(delta))))


MIN_DELTA = 1e-12
"""The smallest δ whose quantile is a finite number in float arithmetic (√(1 − δ) < 1)."""


def checked_delta(delta: object) -> float:
    """``delta`` as a float in [1e-12, 1), or a :class:`ConfigError` naming it (input validation)."""
    if isinstance(delta, (bool, np.bool_)) or not isinstance(delta, (int, float, np.integer, np.floating)) or not 0.0 < delta < 1.0:
        raise ConfigError(f"delta: expected a number in (0, 1), received {short_repr(delta)}")
    if delta < MIN_DELTA:
        raise ConfigError(f"delta: expected a number in [{MIN_DELTA:g}, 1) (smaller ones make Φ⁻¹(√(1 − δ)) infinite), received {short_repr(delta)}")
    return float(delta)


def shadow_epsilon(delta: float) -> float:
    """The ε of the obstacle ε-shadow that keeps the overall bound δ.

    The robot side holds with probability ``√(1 − δ)`` and the obstacle stays in its
    shadow with ``1 − ε``; independence needs ``(1 − ε)√(1 − δ) ≥ 1 − δ``, i.e.
    ``ε ≤ 1 − √(1 − δ)``. We take equality (less conservative than the authors' ε = √δ).
    """
    return 1.0 - np.sqrt(1.0 - checked_delta(delta))


def buffer(normals: np.ndarray, cov: np.ndarray, radius: float | np.ndarray, quantile: float) -> np.ndarray:
    """β for unit normals ``(..., d)`` and the ego covariance ``(..., d, d)`` (broadcasting).

    Raises
    ------
    ConfigError
        Naming the argument: shapes that are not ``(..., d)`` / ``(..., d, d)`` or do not
        broadcast, or NaN / infinite values (checked on the result, diagnosed on failure).
    """
    normals, cov = np.asarray(normals), np.asarray(cov)
    check_buffer_shapes(normals, cov)
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # a non-finite β is refused below, not warned about
            if normals.shape[-1] == 2:
                quad = normals[..., 0] * (cov[..., 0, 0] * normals[..., 0] + 2 * cov[..., 0, 1] * normals[..., 1]) + cov[..., 1, 1] * normals[..., 1] ** 2
            else:
                quad = np.einsum("...i,...ij,...j->...", normals, cov, normals)
            spread = np.sqrt(np.maximum(quad, 0.0))
            beta = radius + quantile * spread
    except (TypeError, ValueError):
        raise ConfigError(f"normals, cov, radius, quantile: expected numbers whose leading axes broadcast, received shapes "
                          f"{normals.shape}, {cov.shape}, {np.shape(radius)}, {np.shape(quantile)}") from None
    if not np.all(np.isfinite(beta)):
        raise non_finite_input(normals=normals, cov=cov, radius=radius, quantile=quantile)
    return beta


# -- input validation of buffer() ---------------------------------------------------------
def check_buffer_shapes(normals: np.ndarray, cov: np.ndarray) -> None:
    """Normals ``(..., d)`` with d = 2 or 3, covariances ``(..., d, d)``."""
    if normals.ndim < 1 or normals.shape[-1] not in (2, 3) or normals.dtype.kind not in "fiu":
        raise ConfigError(f"normals: expected numbers shaped (..., 2) or (..., 3), received shape {normals.shape} of {normals.dtype}")
    d = normals.shape[-1]
    if cov.ndim < 2 or cov.shape[-2:] != (d, d) or cov.dtype.kind not in "fiu":
        raise ConfigError(f"cov: expected numbers shaped (..., {d}, {d}) matching the normals, received shape {cov.shape} of {cov.dtype}")


def non_finite_input(**values: object) -> ConfigError:
    """The error naming the first argument with a NaN or infinite entry (or, if none has
    one, the overflow of the result)."""
    for name, value in values.items():
        array = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(array)):
            return ConfigError(f"{name}: expected finite numbers, received NaN or infinite entries ({short_repr(array.tolist())})")
    return ConfigError(f"{', '.join(values)}: expected values whose buffer is finite, received values that overflow")
