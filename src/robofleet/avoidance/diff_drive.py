"""Differential-drive controller in the B-UAVC: three projections of the goal
(Zhu et al. 2022, Sec. 5.3; ``docs/theory/buavc.md`` "Controllers"; after the BVC controller of
Zhou et al., RA-L 2017).

For a robot at ``p̂`` with heading ``θ`` and goal ``g``:

* ``e``   — the projection of ``g`` onto the cell ``V``;
* ``e_v`` — the projection of ``g`` onto ``V ∩ {p̂ + s h}``, ``h = [cos θ, sin θ]``;
* ``e_ω`` — the projection of ``g`` onto ``V ∩ {p̂ + s ĝ}``, ``ĝ = (g − p̂)/‖g − p̂‖``.

The projections onto a cell ∩ line are 1-D: ``{s : s (A·dir) ≤ b − A·p̂}`` is an
interval and the nearest line point to ``g`` is ``s* = dir·(g − p̂)`` clipped into it.
With ``m = (e_ω + e)/2``::

    v_tmp = h·(p̂ − e_v),   ω_tmp = −atan(ℓ/f)  with (f, ℓ) = R(−θ)(m − p̂),
    k = 0.99 · min(v_max/|v_tmp|, ω_max/|ω_tmp|, 1/Δt),   v = −k v_tmp,   ω = −k ω_tmp / 2.

``ω_tmp`` is the heading-frame angle (mod π) that turns the robot's axis toward ``m``
(reverse driving allowed, as ``v`` follows the sign of ``h·(e_v − p̂)``). The factor
``1/Δt`` in ``k`` (our addition) keeps one step from overshooting ``e_v`` or turning past
``m``, so the controller settles instead of chattering near the goal.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..dynamics.unicycle import UnicycleParams
from .cell3d import project_onto_polytope


def line_interval(origins: np.ndarray, directions: np.ndarray, A: np.ndarray, b: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The interval ``[lo, hi]`` of ``s`` with ``origin + s·direction`` in the cell (``lo > hi`` if empty)."""
    rate = np.einsum("nmd,nd->nm", A, directions)
    room = b - np.einsum("nmd,nd->nm", A, origins)
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = room / rate
    upper = np.where(valid & (rate > 1e-12), bound, np.inf).min(axis=1)
    lower = np.where(valid & (rate < -1e-12), bound, -np.inf).max(axis=1)
    parallel_blocked = np.any(valid & (np.abs(rate) <= 1e-12) & (room < 0), axis=1)
    return np.where(parallel_blocked, np.inf, lower), np.where(parallel_blocked, -np.inf, upper)


def project_onto_cell_line(origins: np.ndarray, directions: np.ndarray, goals: np.ndarray, A: np.ndarray, b: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Projection of ``goals`` onto cell ∩ line ``origin + s·direction`` (unit directions).

    Returns the points ``(N, d)`` and a mask ``(N,)`` of non-empty intersections
    (where empty, the origin is returned).
    """
    lo, hi = line_interval(origins, directions, A, b, valid)
    s_star = np.einsum("nd,nd->n", directions, goals - origins)
    ok = lo <= hi
    s = np.where(ok, np.clip(s_star, lo, hi), 0.0)
    return origins + s[:, None] * directions, ok


def three_projection_control(poses: np.ndarray, goals: np.ndarray, A: np.ndarray, b: np.ndarray, valid: np.ndarray, params: UnicycleParams, dt: float,
                             project: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] = project_onto_polytope) -> np.ndarray:
    """Controls ``(N, 2)`` = ``[v, ω]`` of the three-projection controller.

    Parameters
    ----------
    poses : (N, 3) estimates ``[x, y, θ]``
    goals : (N, 2) current goals (possibly rotated by the deadlock heuristic)
    A, b, valid : cells ``(N, M, 2)``, ``(N, M)``, ``(N, M)``
    params : ``v_max``, ``omega_max``
    dt : control period
    project : exact cell projection ``(points, A, b, valid) -> (proj, ok)``
    """
    p = poses[:, :2]
    theta = poses[:, 2]
    heading = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    gap = goals - p
    dist = np.linalg.norm(gap, axis=-1, keepdims=True)
    to_goal = np.where(dist > 1e-12, gap / np.maximum(dist, 1e-300), heading)
    e, e_ok = project(goals, A, b, valid)
    e_v, _ = project_onto_cell_line(p, heading, goals, A, b, valid)
    e_w, _ = project_onto_cell_line(p, to_goal, goals, A, b, valid)
    m = 0.5 * (e_w + np.where(e_ok[:, None], e, p))
    v_tmp = np.einsum("nd,nd->n", heading, p - e_v)
    rel = m - p
    forward = np.einsum("nd,nd->n", heading, rel)
    lateral = heading[:, 0] * rel[:, 1] - heading[:, 1] * rel[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        w_tmp = np.where(np.abs(forward) > 1e-12, -np.arctan(lateral / forward), -np.sign(lateral) * np.pi / 2)
    w_tmp = np.where(np.hypot(forward, lateral) > 1e-12, w_tmp, 0.0)
    with np.errstate(over="ignore"):  # a huge ratio (fast robot, tiny step) is capped by 1/dt just below
        k = 0.99 * np.minimum(np.minimum(params.v_max / np.maximum(np.abs(v_tmp), 1e-300), params.omega_max / np.maximum(np.abs(w_tmp), 1e-300)), 1.0 / dt)
    return np.stack([-k * v_tmp, -0.5 * k * w_tmp], axis=-1)
