"""Braking rule for double-integrator robots in their B-UAVC (Zhu et al. 2022, Sec. 5.2).

The paper keeps a double integrator safe with a braking heuristic — "the stopping
point under maximal deceleration stays in the cell" — without giving its exact form.
This module is our design of it, stated exactly:

*Braking policy.* ``a_brake(v) = −v̂ · min(a_max, ‖v‖/Δt)``: full deceleration along
the velocity, the last step exactly to rest. From speed ``s`` the robot moves on the
straight segment from ``p`` along ``v̂`` and stops after the distance
(:func:`stopping_distance`, exact for the discrete-time step)

    D(s) = k s Δt − ½ a_max Δt² k² + ½ r Δt,   k = ⌊s / (a_max Δt)⌋,  r = s − k a_max Δt.

*Rule.* Let ``u_des`` be the acceleration that tracks the single-integrator velocity
toward the projected goal ``g*`` (speed ``min(v_max, ‖g* − p‖/Δt, √(2 a_max ‖g* − p‖))``).
Candidates ``u(λ) = λ u_des + (1 − λ) a_brake(v)`` for ``λ = 1, ¾, ½, ¼, ⅛, 0``; the
robot applies the first one for which the three points

    p + v Δt/2,   p⁺ = p + v Δt + ½ u Δt²,   stop(p⁺, v⁺) = p⁺ + D(‖v⁺‖) v̂⁺

lie in the cell, and ``a_brake`` (λ = 0) when none does. A robot whose estimate is
*outside* its cell (noise, or neighbours closer than their buffers) cannot satisfy the
rule; it applies ``u_des`` toward ``g*``, the nearest point of its cell, to get back in.

*Why it is safe (fixed cell).* Within a step the path is the quadratic Bézier curve
with control points ``p``, ``p + v Δt/2``, ``p⁺``, hence inside their convex hull; after
the step the braking path is the segment ``p⁺ → stop(p⁺, v⁺)``. So if the robot's braking
segment lies in a convex cell, the accepted candidate keeps the whole continuous
motion and the next braking segment in the cell. λ = 0 always qualifies: braking keeps
``p⁺`` and the stopping point on the current braking segment (``D(s) ≥ sΔt/2`` puts
``p + vΔt/2`` on it too). By induction a double integrator whose braking segment starts
in the cell never leaves it. Speed: ``v⁺`` is a convex combination of ``v`` and a
velocity of norm ≤ ``v_max``, so ``‖v⁺‖ ≤ v_max`` is kept as well.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.double_integrator import DoubleIntegratorParams, saturate_norm

BLEND_FACTORS = np.array([1.0, 0.75, 0.5, 0.25, 0.125, 0.0])
_TOL = 1e-9


def stopping_distance(speed: np.ndarray, a_max: float, dt: float) -> np.ndarray:
    """Exact distance travelled under the discrete braking policy from ``speed`` (any shape)."""
    s = np.asarray(speed, dtype=float)
    k = np.floor(s / (a_max * dt))
    rest = s - k * a_max * dt
    return k * s * dt - 0.5 * a_max * dt * dt * k * k + 0.5 * rest * dt


def braking_control(velocity: np.ndarray, a_max: float, dt: float) -> np.ndarray:
    """``a_brake(v) = −v̂ · min(a_max, ‖v‖/Δt)`` for velocities ``(..., d)``."""
    v = np.asarray(velocity, dtype=float)
    speed = np.linalg.norm(v, axis=-1, keepdims=True)
    return -v / np.maximum(speed, 1e-300) * np.minimum(a_max, speed / dt)


def stopping_point(position: np.ndarray, velocity: np.ndarray, a_max: float, dt: float) -> np.ndarray:
    """Where the braking policy brings the robot to rest, ``p + D(‖v‖) v̂``."""
    speed = np.linalg.norm(velocity, axis=-1, keepdims=True)
    return position + stopping_distance(speed, a_max, dt) * velocity / np.maximum(speed, 1e-300)


def tracking_control(position: np.ndarray, velocity: np.ndarray, target: np.ndarray, params: DoubleIntegratorParams, dt: float) -> np.ndarray:
    """``u_des``: the acceleration toward the single-integrator velocity aimed at ``target``."""
    gap = target - position
    dist = np.linalg.norm(gap, axis=-1, keepdims=True)
    speed = np.minimum(np.minimum(params.v_max, dist / dt), np.sqrt(2.0 * params.a_max * dist))
    v_des = gap / np.maximum(dist, 1e-300) * speed
    return saturate_norm((v_des - velocity) / dt, params.a_max)


def braking_rule(position: np.ndarray, velocity: np.ndarray, target: np.ndarray, A: np.ndarray, b: np.ndarray, valid: np.ndarray, params: DoubleIntegratorParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Accelerations ``(N, d)`` of the braking rule, vectorized over robots and candidates.

    Parameters
    ----------
    position, velocity : (N, d) position estimates and velocities
    target : (N, d) projected goals ``g*`` (points of the cells)
    A, b, valid : cells ``(N, M, d)``, ``(N, M)``, ``(N, M)``
    params : ``a_max``, ``v_max``
    dt : control period

    Returns
    -------
    control : (N, d)
    braking : (N,) bool, True where no blend passed and ``a_brake`` was applied
    """
    p = np.asarray(position, dtype=float)
    v = np.asarray(velocity, dtype=float)
    u_des = tracking_control(p, v, np.asarray(target, dtype=float), params, dt)
    u_brake = braking_control(v, params.a_max, dt)
    lam = BLEND_FACTORS[None, :, None]
    cand = lam * u_des[:, None, :] + (1.0 - lam) * u_brake[:, None, :]  # (N, K, d)
    p_next = p[:, None, :] + v[:, None, :] * dt + 0.5 * cand * dt * dt
    v_next = v[:, None, :] + cand * dt
    stop = stopping_point(p_next, v_next, params.a_max, dt)
    mid = np.broadcast_to((p + 0.5 * dt * v)[:, None, :], p_next.shape)
    ok = _inside(mid, A, b, valid) & _inside(p_next, A, b, valid) & _inside(stop, A, b, valid)
    first = np.argmax(ok, axis=1)
    any_ok = ok[np.arange(len(p)), first]
    control = np.where(any_ok[:, None], cand[np.arange(len(p)), first], u_brake)
    outside = ~_inside(p[:, None, :], A, b, valid)[:, 0]
    control = np.where(outside[:, None], u_des, control)
    return control, ~any_ok & ~outside


def _inside(points, A, b, valid) -> np.ndarray:
    """``(N, K)`` mask: candidate points ``(N, K, d)`` inside robot ``n``'s cell."""
    slack = np.einsum("nmd,nkd->nkm", A, points) - b[:, None, :]
    return np.all((slack <= _TOL) | ~valid[:, None, :], axis=-1)
