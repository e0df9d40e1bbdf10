"""Single integrator ``ṗ = u`` (Zhu et al. 2022, Sec. on single-integrator robots)."""

from __future__ import annotations

import numpy as np


def step(position: np.ndarray, velocity: np.ndarray, dt: float) -> np.ndarray:
    """Exact discretisation ``p[k+1] = p[k] + u[k] Δt`` for arrays ``(..., d)``."""
    return position + velocity * dt


def saturate(velocity: np.ndarray, v_max: float | np.ndarray) -> np.ndarray:
    """Scale each velocity ``(..., d)`` down to norm at most ``v_max`` (keeps direction)."""
    speed = np.linalg.norm(velocity, axis=-1, keepdims=True)
    scale = np.minimum(1.0, np.asarray(v_max, dtype=float)[..., None] / np.maximum(speed, 1e-300)) if np.ndim(v_max) else np.minimum(1.0, v_max / np.maximum(speed, 1e-300))
    return velocity * scale
