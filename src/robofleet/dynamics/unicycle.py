"""Differential-drive (unicycle) robot ``ẋ = v cos θ, ẏ = v sin θ, θ̇ = ω`` (Zhu et al. 2022,
Sec. 5.3), integrated with the second-order Runge–Kutta (midpoint) rule as in the
authors' release.

State ``(..., 3)`` = ``[x, y, θ]``; control ``(..., 2)`` = ``[v, ω]``, saturated to
``|v| ≤ v_max`` and ``|ω| ≤ ω_max`` (reverse driving allowed).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from pydantic import Field

from ..core.config import SpecModel


class UnicycleParams(SpecModel):
    """Limits of a differential-drive robot."""

    v_max: float = Field(gt=0, description="maximal forward/backward speed [m/s]")
    omega_max: float = Field(gt=0, description="maximal turn rate [rad/s]")


def saturate(control: np.ndarray, params: UnicycleParams) -> np.ndarray:
    """Clip ``v`` to ``[−v_max, v_max]`` and ``ω`` to ``[−ω_max, ω_max]``."""
    c = np.asarray(control, dtype=float)
    return np.stack([np.clip(c[..., 0], -params.v_max, params.v_max), np.clip(c[..., 1], -params.omega_max, params.omega_max)], axis=-1)


def derivative(x: Any, y: Any, theta: Any, v: Any, omega: Any, sin: Callable[[Any], Any] = np.sin,
               cos: Callable[[Any], Any] = np.cos) -> tuple[Any, Any, Any]:
    """Continuous-time right-hand side ``(ẋ, ẏ, θ̇)``; ``sin``/``cos`` may be casadi's."""
    return v * cos(theta), v * sin(theta), omega


def step(state: np.ndarray, control: np.ndarray, dt: float, params: UnicycleParams) -> np.ndarray:
    """One RK2 (midpoint) step of length ``dt`` with the saturated control held constant.

    ``θ_m = θ + ω Δt/2``; ``x⁺ = x + v cos θ_m Δt``; ``y⁺ = y + v sin θ_m Δt``; ``θ⁺ = θ + ω Δt``.
    """
    s = np.asarray(state, dtype=float)
    c = saturate(control, params)
    return np.stack(_rk2(s[..., 0], s[..., 1], s[..., 2], c[..., 0], c[..., 1], dt, np.sin, np.cos), axis=-1)


def symbolic_step(x: Any, u: Any, dt: float, params: UnicycleParams) -> Any:
    """The RK2 step for casadi column vectors ``x`` (3) and ``u`` (2)."""
    import casadi as ca

    return ca.vertcat(*_rk2(x[0], x[1], x[2], u[0], u[1], dt, ca.sin, ca.cos))


def _rk2(x, y, theta, v, omega, dt, sin, cos):
    dx, dy, dth = derivative(x, y, theta, v, omega, sin, cos)
    mx, my, mth = derivative(x + 0.5 * dt * dx, y + 0.5 * dt * dy, theta + 0.5 * dt * dth, v, omega, sin, cos)
    return x + dt * mx, y + dt * my, theta + dt * mth
