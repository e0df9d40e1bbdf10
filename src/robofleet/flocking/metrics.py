"""Formation metrics of Gervasi & Prencipe, TR-01-24.

* :func:`d_distance`: the 𝒟-distance of Def. 3.1 (minimum total distance over all
  matchings, an assignment problem solved exactly by ``scipy.optimize.linear_sum_assignment``,
  O(n³)) and the per-robot distances ρ_i under the optimal matching.
* :func:`estimated_target` / :func:`real_target`: the directed targets 𝒯^{φ_B(t)} and
  𝒯^{ψ_L(t)} of Sec. 4.2 (Def. 3.2).
* :func:`delta_series`: Δ_e(t) and Δ_r(t) over a run (Sec. 4.2).
* :func:`convergence_time`: first time after which Δ stays ≤ ξ (Def. 3.3-3.4: the
  approximate flocking problem is solved from ``t_1`` on).
* :func:`slot_changes`: how often followers change their target slot (Sec. 5.1, problem 3).

The leader's own term is always zero (targets put the pattern's leader on the fleet's
leader), so all functions work on the followers only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from ..core.errors import ConfigError
from .patterns import Pattern


@dataclass(frozen=True)
class DDistance:
    """Result of :func:`d_distance`.

    ``value`` = 𝒟(C, G); ``assignment[i]`` = index π'(i) of the point of G matched to
    ``c_i``; ``rho[i]`` = ρ_i(C, G) = dist(c_i, g_{π'(i)}).
    """

    value: float
    assignment: np.ndarray
    rho: np.ndarray


def _points(arr, name: str) -> np.ndarray:
    a = np.asarray(arr, dtype=float)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ConfigError(f"{name}: expected an (n, 2) array, received shape {a.shape}")
    return a


def d_distance(c, g) -> DDistance:
    """𝒟(C, G) = min_π Σ_i dist(c_i, g_π(i)) (Def. 3.1), with ρ_i.

    Parameters
    ----------
    c, g: ``(n, 2)`` configurations of equal size.

    Complexity O(n³) (Jonker-Volgenant via ``linear_sum_assignment``); the cost matrix
    takes O(n²) memory (8 MB for n = 1000).
    """
    c, g = _points(c, "c"), _points(g, "g")
    if len(c) != len(g):
        raise ConfigError(f"g: expected {len(c)} points like c, received {len(g)}")
    cost = cdist(c, g)
    rows, cols = linear_sum_assignment(cost)
    assignment = np.empty(len(c), dtype=np.intp)
    assignment[rows] = cols
    rho = cost[rows, cols][np.argsort(rows)]
    return DDistance(float(rho.sum()), assignment, rho)


def rotation_onto(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The proper rotation ``(2, 2)`` taking direction ``src`` onto direction ``dst``."""
    angle = np.arctan2(dst[1], dst[0]) - np.arctan2(src[1], src[0])
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def place(points: np.ndarray, leader: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Pattern points rotated by ``rotation`` and translated onto ``leader``."""
    return points @ rotation.T + leader


def estimated_target(pattern: Pattern, leader, followers) -> np.ndarray:
    """𝒯^{φ_B}: ℙ on the leader, rotated so that B_P lies on the line L–B on B's side.

    (Sec. 4.2.) Returns NaNs when B = L (the axis is undefined, footnote 3).
    """
    leader = np.asarray(leader, dtype=float)
    to_leader = leader - np.asarray(followers, dtype=float).mean(axis=0)
    if np.linalg.norm(to_leader) == 0.0:
        return np.full_like(pattern.points, np.nan)
    return place(pattern.points, leader, rotation_onto(pattern.axis, to_leader))


def real_target(pattern: Pattern, leader, heading: float) -> np.ndarray:
    """𝒯^{ψ_L}: ℙ on the leader, its x axis along the leader's heading ``ψ_L`` (Def. 3.2)."""
    c, s = np.cos(heading), np.sin(heading)
    return place(pattern.points, np.asarray(leader, dtype=float), np.array([[c, -s], [s, c]]))


def delta_series(positions: np.ndarray, headings: np.ndarray, pattern: Pattern) -> tuple[np.ndarray, np.ndarray]:
    """Δ_e(t) and Δ_r(t) (Sec. 4.2) for every sampled step.

    Parameters
    ----------
    positions: ``(T, 1 + m, 2)`` true positions, leader at index 0.
    headings: ``(T,)`` leader heading ψ_L(t) (radians).
    pattern: the pattern ℙ with ``m`` points.
    """
    pos = np.asarray(positions, dtype=float)
    if pos.ndim != 3 or pos.shape[2] != 2 or pos.shape[1] != pattern.size + 1:
        raise ConfigError(f"positions: expected shape (T, {pattern.size + 1}, 2), received {pos.shape}")
    leader, followers = pos[:, 0], pos[:, 1:]
    to_leader = leader - followers.mean(axis=1)
    ang_e = np.arctan2(to_leader[:, 1], to_leader[:, 0]) - np.arctan2(pattern.axis[1], pattern.axis[0])
    undefined = np.linalg.norm(to_leader, axis=1) == 0.0
    target_e = _rotated_targets(pattern.points, leader, ang_e)
    target_r = _rotated_targets(pattern.points, leader, np.asarray(headings, dtype=float))
    de = _assignment_costs(followers, target_e)
    de[undefined] = np.nan
    return de, _assignment_costs(followers, target_r)


def _rotated_targets(points: np.ndarray, leader: np.ndarray, angles: np.ndarray) -> np.ndarray:
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x, y = points[:, 0][None], points[:, 1][None]
    return np.stack([c * x - s * y, s * x + c * y], -1) + leader[:, None, :]


def _assignment_costs(followers: np.ndarray, targets: np.ndarray) -> np.ndarray:
    cost = np.linalg.norm(followers[:, :, None, :] - targets[:, None, :, :], axis=-1)  # (T, m, m)
    out = np.empty(len(cost))
    for t, c in enumerate(cost):  # one O(m³) assignment per step; scipy has no batched version
        rows, cols = linear_sum_assignment(c)
        out[t] = c[rows, cols].sum()
    return out


def convergence_time(times: np.ndarray, values: np.ndarray, xi: float) -> float:
    """First sampled time from which ``values ≤ xi`` holds until the end (``nan`` if never).

    This is ``t_1`` of Def. 3.4 restricted to the simulated horizon.
    """
    ok = np.asarray(values) <= xi
    stays = np.flip(np.logical_and.accumulate(np.flip(ok)))
    return float(np.asarray(times)[np.argmax(stays)]) if stays.any() else float("nan")


def slot_changes(robots: np.ndarray, slots: np.ndarray, n_followers: int) -> np.ndarray:
    """Per follower, how many consecutive cycles chose different target slots.

    ``robots`` and ``slots`` are the cycle log in time order (``slot = -1`` means the
    follower waited; waits are ignored).
    """
    robots, slots = np.asarray(robots), np.asarray(slots)
    keep = slots >= 0
    robots, slots = robots[keep], slots[keep]
    order = np.argsort(robots, kind="stable")
    r, s = robots[order], slots[order]
    changed = (r[1:] == r[:-1]) & (s[1:] != s[:-1])
    return np.bincount(r[1:][changed], minlength=n_followers)
