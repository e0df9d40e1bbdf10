"""Chance-constrained buffers of the B-UAVC (Zhu et al. 2022; notes/buavc.md "Buffer").

``β = r_s + Φ⁻¹(√(1 − δ)) · √(aᵀ Σ_i a)`` with ``‖a‖ = 1``. Robot ``i`` then stays on its
side of the separator, at least ``r_s`` from it, with probability ``≥ √(1 − δ)``; robot
``j`` likewise; independence gives ``≥ 1 − δ`` for the pair, and the slab of width
``2 r_s`` separates the two discs.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri

from ..core.errors import ConfigError


def confidence_quantile(delta: float) -> float:
    """``Φ⁻¹(√(1 − δ))``; e.g. 1.632 for δ = 0.10, 2.575 for δ = 0.01."""
    if not 0.0 < delta < 1.0:
        raise ConfigError(f"delta: expected a number in (0, 1), received {delta!r}")
    return float(ndtri(np.sqrt(1.0 - delta)))


def shadow_epsilon(delta: float) -> float:
    """The ε of the obstacle ε-shadow that keeps the overall bound δ.

    The robot side holds with probability ``√(1 − δ)`` and the obstacle stays in its
    shadow with ``1 − ε``; independence needs ``(1 − ε)√(1 − δ) ≥ 1 − δ``, i.e.
    ``ε ≤ 1 − √(1 − δ)``. We take equality (less conservative than the authors' ε = √δ).
    """
    return 1.0 - np.sqrt(1.0 - delta)


def buffer(normals: np.ndarray, cov: np.ndarray, radius: float | np.ndarray, quantile: float) -> np.ndarray:
    """β for unit normals ``(..., d)`` and the ego covariance ``(..., d, d)`` (broadcasting)."""
    if normals.shape[-1] == 2:
        quad = normals[..., 0] * (cov[..., 0, 0] * normals[..., 0] + 2 * cov[..., 0, 1] * normals[..., 1]) + cov[..., 1, 1] * normals[..., 1] ** 2
    else:
        quad = np.einsum("...i,...ij,...j->...", normals, cov, normals)
    spread = np.sqrt(np.maximum(quad, 0.0))
    return radius + quantile * spread
