"""Braking rule for double-integrator robots in their B-UAVC (Zhu et al. 2022, Sec. 5.2).

The paper keeps a double integrator safe with a braking heuristic — "the stopping
point under maximal deceleration stays in the cell" — without giving its exact form.
This module is our design of it, stated exactly:

*Braking policy.* ``a_brake(v) = −v̂ · min(a_max, ‖v‖/Δt)``: full deceleration along
the velocity, the last step exactly to rest. From speed ``s`` the robot moves on the
straight segment from ``p`` along ``v̂`` and stops after the distance
(:func:`stopping_distance`, exact for the discrete-time step)

    D(s) = k s Δt − ½ a_max Δt² k² + ½ r Δt,   k = ⌊s / (a_max Δt)⌋,  r = s − k a_max Δt.

*Braking segment.* ``S(p, v) = [p, stop(p, v)]``, ``stop(p, v) = p + D(‖v‖) v̂``
(:func:`stopping_point`): the path the robot covers if it brakes from now on. A single
integrator stops at once: its segment is its point. The policy depends on the velocity
alone and the braking path from ``p⁺`` is the rest of the braking path from ``p``, so
braking keeps ``stop(p⁺, v⁺) = stop(p, v)`` and ``S(k+1) ⊂ S(k)``.

*Cells.* The simulation builds every row that concerns a robot with a non-degenerate
segment from the segments (:mod:`.segment_cells`): robot pairs are split by the
maximum-margin plane between ``S_i`` and ``S_j``, each side tightened by the pair's mean
radius ``(r_i + r_j)/2`` and its own chance buffer; obstacles by the maximum-margin plane
between ``S_i`` and the obstacle's shadow, tightened by ``r_i`` and the buffer; walls as
for points. Pairs of points keep the separator of appendix B (with ``Σ = 0`` the same
perpendicular bisector).

*Rule.* Let ``u_des`` be the acceleration that tracks the single-integrator velocity
toward the projected goal ``g*`` (speed ``min(v_max, ‖g* − p‖/Δt, √(2 a_max ‖g* − p‖))``).
Candidates ``u(λ) = λ u_des + (1 − λ) a_brake(v)`` for ``λ = 1, ¾, ½, ¼, ⅛, 0``; the
robot applies the first one for which the three points

    p + v Δt/2,   p⁺ = p + v Δt + ½ u Δt²,   stop(p⁺, v⁺) = p⁺ + D(‖v⁺‖) v̂⁺

lie in the cell (to ``10⁻⁹`` m), and ``a_brake`` (λ = 0) when none does. A robot whose
estimate is *outside* its cell by more than ``10⁻⁶`` m (noise, or neighbours closer than
their buffers) cannot satisfy the rule; it applies ``u_des`` toward ``g*``, the nearest
point of its cell, to get back in.

*One step.* Within a step the path is the quadratic Bézier curve with control points
``p``, ``p + v Δt/2``, ``p⁺``, hence inside their convex hull; after the step the braking
segment is ``S(k+1) = [p⁺, stop(p⁺, v⁺)]``. If ``S(k)`` lies in the (convex) cell, the
accepted candidate keeps the whole motion of the step and ``S(k+1)`` in it, and λ = 0
always qualifies: braking keeps ``p⁺`` and the stopping point on ``S(k)``, and
``D(s) ≥ sΔt/2`` (the first braking step alone covers ``sΔt − ½ min(a_max, s/Δt) Δt² ≥
sΔt/2``) puts ``p + vΔt/2`` on it too. Speed: ``v⁺`` is a convex combination of ``v`` and
a velocity of norm ≤ ``v_max``, so ``‖v⁺‖ ≤ v_max`` is kept, and so is every speed within
the step (the velocity is linear in time).

*Theorem (exact estimates, across cell changes).* Premises: (1) ``Σ = 0`` and
``Σ_o = 0``; (2) every robot is a double integrator under this rule or a single
integrator under the one-step controller (whose next position lies in its cell); (3) the
robots start at rest, pairwise at least ``r_i + r_j`` apart, at least ``r_i`` from every
obstacle and inside the walls by ``r_i``; (4) the local box is large enough,
``R_loc ≥ 2 max_i (r_i + ρ_i)`` with the reach ``ρ_i = v_max Δt + D(v_max)`` of a double
integrator and ``ρ_i = v_max Δt`` of a single integrator. Then at every step the
invariant

    I(k):  dist(S_i, S_j) ≥ r_i + r_j for every pair,  dist(S_i, O) ≥ r_i for every
           obstacle shadow O,  S_i inside the walls shrunk by r_i

holds, no robot leaves its cell, and no two robots, and no robot and obstacle, ever
touch — also between the steps.

*Proof.* I(0) is premise (3). Assume I(k).
(a) ``S_i(k)`` lies in its cell ``V_i(k)``: the plane of a pair row is ``dist(S_i, S_j)/2
≥ (r_i + r_j)/2`` from either segment, the row's tightening (for two points, with
``Σ = 0``, the perpendicular bisector, tightened alike); an obstacle row's plane touches
the shadow orthogonally to a closest pair, so ``S_i`` is ``dist(S_i, O) ≥ r_i`` from it; a
wall row holds at both ends of ``S_i``, hence on all of it.
(b) By (a) the estimate ``p_i``, an end of ``S_i(k)``, lies in ``V_i(k)``, so the rule
does not take the *outside* branch, and by *One step* the robot's path during step ``k``
and ``S_i(k+1)`` lie in ``V_i(k)`` (a robot for which rounding fails every candidate
applies ``a_brake``, the λ = 0 candidate itself); a single integrator's straight step
does too (premise 2).
(c) I(k+1): two robots in each other's local box have cells on the two sides of one
plane, each tightened by ``(r_i + r_j)/2``, so ``S_i(k+1)`` and ``S_j(k+1)``, and their
paths during the step, are ``r_i + r_j`` apart. Two robots that are not,
``‖p_i − p_j‖ ≥ |p_i − p_j|_∞ > R_loc``, and a robot moves at most ``v_max Δt`` in a step
and stops within ``D(v_max)`` of where it is, so ``S_i(k+1)`` lies within ``ρ_i`` of
``p_i(k)``, as does its path: by (4) they stay ``r_i + r_j`` apart. Obstacles and walls
in the local box are rows of ``V_i(k)``; the others are farther than ``R_loc ≥ r_i + ρ_i``.
By induction, I(k) holds for every ``k``. ∎

Rounding: the rule accepts points up to ``10⁻⁹`` m outside a row, so the distances above
hold up to ``2·10⁻⁹`` m and (a) up to ``10⁻⁹`` m; the error does not accumulate, because
every step's cells are built from the segments as they are, and it stays far below the
``10⁻⁶`` m beyond which an estimate counts as outside its cell.

*With noise.* The cells are built from the estimated segments ``[p̂_i, stop(p̂_i, v_i)]``
(velocities are measured exactly), the true segment shifted by the estimate's error
``e_i``. The chance buffer ``β_i = Φ⁻¹(√(1 − δ)) √(aᵀΣ_i a)`` of each row then keeps the
true segment on its side with probability ≥ ``√(1 − δ)`` whenever the estimated one is
(the argument of docs/theory/buavc.md "Buffer" holds for any plane both robots compute alike),
which gives the per-pair, per-step bound δ of Sec. 4 at that step. The induction across
steps does not carry over: the next estimate moves the segment by ``e_i(k+1) − e_i(k)``,
so it may start outside the new cell; the rule then brakes (estimate inside its cell) or
heads back at ``u_des`` (estimate outside), and nothing exact is claimed for that step.
Teams of other models (unicycles, MPC teams, quadrotors) do not keep their cells within
a step (:data:`~robofleet.avoidance.guarantees.LEAVES_CELL`): a double integrator next to
one of them keeps its own cell, but no bound on that pair's distance is claimed.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.double_integrator import DoubleIntegratorParams, saturate_norm

BLEND_FACTORS = np.array([1.0, 0.75, 0.5, 0.25, 0.125, 0.0])
_TOL = 1e-9
"""How far [m] a candidate's points may lie outside a row (rounding)."""
OUTSIDE_TOL = 1e-6
"""How far [m] beyond a row an estimate lies before the rule treats it as outside its cell
(well above the rounding the accepted points carry, module docstring)."""


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
        The guarantee across steps needs them built from the braking segments
        (:func:`~.segment_cells.with_braking_segments`, module docstring).
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
    outside = ~_inside(p[:, None, :], A, b, valid, OUTSIDE_TOL)[:, 0]
    control = np.where(outside[:, None], u_des, control)
    return control, ~any_ok & ~outside


def _inside(points, A, b, valid, tol: float = _TOL) -> np.ndarray:
    """``(N, K)`` mask: candidate points ``(N, K, d)`` inside robot ``n``'s cell (to ``tol``)."""
    slack = np.einsum("nmd,nkd->nkm", A, points) - b[:, None, :]
    return np.all((slack <= tol) | ~valid[:, None, :], axis=-1)
