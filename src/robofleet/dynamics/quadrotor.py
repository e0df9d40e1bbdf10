"""Quadrotor model of Zhu et al. 2022, appendix D (Parrot Bebop 2, identified parameters).

State ``x = [p (3), v (3), φ, θ, ψ] ∈ R⁹``; input ``u = [φ_c, θ_c, v_zc, ψ̇_c] ∈ R⁴``
(commanded roll, pitch, vertical speed, yaw rate). Appendix D, Eqs. (52)–(53):

    ṗ = v
    [v̇_x, v̇_y] = R_Z(ψ) [tan θ, −tan φ] g − [k_Dx v_x, k_Dy v_y]
    v̇_z = (k_vz v_zc − v_z) / τ_vz
    φ̇ = (k_φ φ_c − φ) / τ_φ,   θ̇ = (k_θ θ_c − θ) / τ_θ,   ψ̇ = ψ̇_c

integrated with the classical fourth-order Runge–Kutta rule, the input held over Δt.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from pydantic import Field

from ..core.config import SpecModel

STATE_DIM = 9
CONTROL_DIM = 4


class QuadrotorParams(SpecModel):
    """Appendix D parameters (defaults = the identified Bebop 2 values) and input limits."""

    k_Dx: float = Field(0.25, ge=0)
    k_Dy: float = Field(0.33, ge=0)
    k_vz: float = Field(1.2270, gt=0)
    tau_vz: float = Field(0.3367, gt=0)
    k_phi: float = Field(1.1260, gt=0)
    tau_phi: float = Field(0.2368, gt=0)
    k_theta: float = Field(1.1075, gt=0)
    tau_theta: float = Field(0.2318, gt=0)
    gravity: float = Field(9.81, gt=0)
    tilt_max: float = Field(0.35, gt=0, lt=1.5, description="|φ_c|, |θ_c| limit [rad]")
    vz_max: float = Field(1.0, gt=0, description="|v_zc| limit [m/s]")
    yaw_rate_max: float = Field(1.0, gt=0, description="|ψ̇_c| limit [rad/s]")

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper input bounds ``(4,)``."""
        hi = np.array([self.tilt_max, self.tilt_max, self.vz_max, self.yaw_rate_max])
        return -hi, hi


def derivative(x: list, u: list, params: QuadrotorParams, sin: Callable[[Any], Any] = np.sin, cos: Callable[[Any], Any] = np.cos,
               tan: Callable[[Any], Any] = np.tan) -> list:
    """Appendix D right-hand side on component lists (numpy arrays or casadi symbols)."""
    _, _, _, vx, vy, vz, phi, theta, psi = x
    phi_c, theta_c, vz_c, yaw_rate_c = u
    g = params.gravity
    ax_body, ay_body = tan(theta) * g, -tan(phi) * g
    return [
        vx,
        vy,
        vz,
        cos(psi) * ax_body - sin(psi) * ay_body - params.k_Dx * vx,
        sin(psi) * ax_body + cos(psi) * ay_body - params.k_Dy * vy,
        (params.k_vz * vz_c - vz) / params.tau_vz,
        (params.k_phi * phi_c - phi) / params.tau_phi,
        (params.k_theta * theta_c - theta) / params.tau_theta,
        yaw_rate_c,
    ]


def rk4(x: list, u: list, dt: float, params: QuadrotorParams, **ops: Callable[[Any], Any]) -> list:
    """One classical RK4 step on component lists."""
    k1 = derivative(x, u, params, **ops)
    k2 = derivative([a + 0.5 * dt * k for a, k in zip(x, k1)], u, params, **ops)
    k3 = derivative([a + 0.5 * dt * k for a, k in zip(x, k2)], u, params, **ops)
    k4 = derivative([a + dt * k for a, k in zip(x, k3)], u, params, **ops)
    return [a + dt / 6.0 * (p + 2 * q + 2 * r + s) for a, p, q, r, s in zip(x, k1, k2, k3, k4)]


def saturate(control: np.ndarray, params: QuadrotorParams) -> np.ndarray:
    """Clip each input to its bounds."""
    lo, hi = params.control_bounds()
    return np.clip(np.asarray(control, dtype=float), lo, hi)


def step(state: np.ndarray, control: np.ndarray, dt: float, params: QuadrotorParams) -> np.ndarray:
    """State ``(..., 9)`` after ``dt`` under the saturated input ``(..., 4)`` (RK4)."""
    s = np.asarray(state, dtype=float)
    c = saturate(control, params)
    out = rk4([s[..., k] for k in range(STATE_DIM)], [c[..., k] for k in range(CONTROL_DIM)], dt, params)
    return np.stack(out, axis=-1)


def symbolic_step(x: Any, u: Any, dt: float, params: QuadrotorParams) -> Any:
    """The RK4 step for casadi column vectors ``x`` (9) and ``u`` (4)."""
    import casadi as ca

    out = rk4([x[k] for k in range(STATE_DIM)], [u[k] for k in range(CONTROL_DIM)], dt, params, sin=ca.sin, cos=ca.cos, tan=ca.tan)
    return ca.vertcat(*out)


def hover_control(n: int) -> np.ndarray:
    """The level-attitude, zero-climb input ``(n, 4)`` (the MPC's safe fallback)."""
    return np.zeros((n, CONTROL_DIM))


def braking_control(state: np.ndarray, params: QuadrotorParams, time_constant: float = 0.5) -> np.ndarray:
    """Inputs ``(n, 4)`` that decelerate the quadrotor (the MPC's safe fallback).

    Horizontal: the steady tilt whose thrust gives the acceleration ``−v_xy/τ_b``
    (Eq. (52) solved for the commanded angles at zero drag, ``tan θ = a_x'/g``,
    ``tan φ = −a_y'/g`` in the yaw frame, divided by the attitude gains), clipped to
    ``tilt_max``; vertical speed command 0; yaw rate 0.
    """
    s = np.asarray(state, dtype=float)
    v = s[:, 3:5]
    psi = s[:, 8]
    accel = -v / time_constant
    c, sn = np.cos(psi), np.sin(psi)
    ax_body = c * accel[:, 0] + sn * accel[:, 1]
    ay_body = -sn * accel[:, 0] + c * accel[:, 1]
    theta_c = np.arctan(ax_body / params.gravity) / params.k_theta
    phi_c = -np.arctan(ay_body / params.gravity) / params.k_phi
    u = np.column_stack([phi_c, theta_c, np.zeros(len(s)), np.zeros(len(s))])
    return saturate(u, params)
