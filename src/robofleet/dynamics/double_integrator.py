"""Double integrator ``p̈ = a`` with acceleration and speed limits (Zhu et al. 2022, Sec. 5.2).

State ``(..., 2d)`` = ``[p, v]``; control ``(..., d)`` = acceleration. The step is the
exact zero-order-hold discretisation

    p[k+1] = p[k] + v[k] Δt + ½ a[k] Δt²,    v[k+1] = v[k] + a[k] Δt,

with the commanded acceleration saturated to ``‖a‖ ≤ a_max``. The speed limit
``v_max`` is the controller's duty (see :mod:`robofleet.avoidance.braking`), so that the
motion within a step stays an exact parabola (a quadratic Bézier curve with control
points ``p``, ``p + v Δt/2``, ``p[k+1]``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from ..core.config import SpecModel


class DoubleIntegratorParams(SpecModel):
    """Limits of a double-integrator robot (both required, both > 0)."""

    a_max: float = Field(gt=0, description="maximal acceleration norm [m/s²]")
    v_max: float = Field(gt=0, description="maximal speed [m/s]")


def split_state(state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(p, v)`` views of a state ``(..., 2d)``."""
    d = state.shape[-1] // 2
    return state[..., :d], state[..., d:]


def saturate_norm(vectors: np.ndarray, limit: float | np.ndarray) -> np.ndarray:
    """Scale vectors ``(..., d)`` down to norm ≤ ``limit`` (direction kept)."""
    norm = np.linalg.norm(vectors, axis=-1, keepdims=True)
    return vectors * np.minimum(1.0, limit / np.maximum(norm, 1e-300))


def step(state: np.ndarray, control: np.ndarray, dt: float, params: DoubleIntegratorParams) -> np.ndarray:
    """Exact discretisation over ``dt`` with the acceleration saturated to ``a_max``.

    Parameters
    ----------
    state : (..., 2d) array ``[p, v]``
    control : (..., d) array of commanded accelerations
    dt : step length [s]
    params : limits

    Returns
    -------
    (..., 2d) array, the state after ``dt``.
    """
    p, v = split_state(np.asarray(state, dtype=float))
    a = saturate_norm(np.asarray(control, dtype=float), params.a_max)
    return np.concatenate([p + v * dt + 0.5 * a * dt * dt, v + a * dt], axis=-1)


def symbolic_step(x: Any, u: Any, dt: float, params: DoubleIntegratorParams, dim: int) -> Any:
    """The same map for casadi column vectors (no saturation: the MPC bounds the input)."""
    p, v = x[:dim], x[dim:]
    return _vertcat(p + v * dt + 0.5 * u * dt * dt, v + u * dt)


def _vertcat(*parts):
    import casadi as ca

    return ca.vertcat(*parts)
