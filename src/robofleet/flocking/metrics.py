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
* :func:`run_results`: the per-run results a simulation writes into ``trace.results``
  (documented in :data:`RESULTS`), among them ``success``: the estimated formation was
  formed up to ξ and kept (:func:`formed_and_kept`).

The leader's own term is always zero (targets put the pattern's leader on the fleet's
leader), so all functions work on the followers only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from ..core.errors import ConfigError
from .leader import ConditionReport, LeaderCourse, check_conditions, condition4_max
from .patterns import Pattern
from .schedulers import CycleLog

#: The share of the run, at its end, over which the tail means and ``success`` are taken.
TAIL_FRACTION = 0.1

RESULTS: dict[str, str] = {
    "pattern": "the pattern's name (wedge, line, spread, random<n>, points, or the pattern file's stem)",
    "algorithm": "algorithm.kind",
    "scheduler": "scheduler.kind (fsync, ssync, async)",
    "n_followers": "followers m (positions hold the leader at index 0 and the followers at 1..m)",
    "xi": "ξ of Def. 3.3 used by the run (auto: 2 Σ_i k^{f_i}, twice the bound of condition (3))",
    "delta_e_final": "Δ_e at the last sample: 𝒟-distance to the estimated target (Sec. 4.2)",
    "delta_r_final": "Δ_r at the last sample: 𝒟-distance to the real target, directed by the leader's heading (Sec. 4.2)",
    "delta_e_tail": "mean Δ_e over the last 10 % of the samples",
    "delta_r_tail": "mean Δ_r over the last 10 % of the samples",
    "convergence_time_e": "first time from which Δ_e ≤ ξ until the end (t_1 of Def. 3.4; NaN if never)",
    "convergence_time_r": "first time from which Δ_r ≤ ξ until the end (NaN if never)",
    "converged_e": "whether Δ_e ≤ ξ holds from some sample to the end (approximate undirected flocking on the horizon)",
    "converged_r": "whether Δ_r ≤ ξ holds from some sample to the end (approximate directed flocking on the horizon)",
    "delta_r_within_xi_last_third": "share of the samples of the last third of the run with Δ_r ≤ ξ",
    "slot_changes": "times a follower chose a different slot than at its previous cycle (waits ignored; Sec. 5.1)",
    "cycles": "Look-Compute-Move cycles run by all followers",
    "seen_moving_share": "share of Looks that saw at least one other follower while it moved (asynchrony)",
    "v_leader": "v_L, the leader's speed",
    "omega_leader": "ω_L, the largest turn rate of the leader's course",
    "slot_speed": "v_L + ω_L R_P, the largest speed of a slot (Fig. 2)",
    "v_min": "min_i v_{f_i}, the slowest follower's speed",
    "sum_k": "Σ_i k^{f_i} with the Moves measured on the cycle log (condition (3))",
    "condition_4_max": "max_t Σ_i (v_L + ω_L R_P) τ̄_{f_i}(t) measured on the cycle log (condition (4))",
    "condition_1": "v_L < min_i v_{f_i} (Sec. 3.2, (1))",
    "condition_2": "v_L + ω_L R_P < min_i v_{f_i} (Sec. 3.2, (2))",
    "condition_3": "Σ_i k^{f_i} ≤ ξ on the measured Moves (Sec. 3.2, (3))",
    "condition_4": "condition (4) of Sec. 3.2 on the measured Moves",
    "delta_m_final": "non-lb-symmetric patterns only: Δ_e up to reflection (to the nearer of ℙ and its mirror image) at the last sample",
    "convergence_time_m": "non-lb-symmetric patterns only: first time from which Δ_e up to reflection ≤ ξ until the end",
    "formed_mirror_image": "non-lb-symmetric patterns only: whether the mirror image of ℙ is nearer than ℙ at the end",
}
"""Every key :func:`run_results` (and the simulation: pattern, algorithm, scheduler) may write, with its meaning."""


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


def d_distance(c: np.ndarray, g: np.ndarray) -> DDistance:
    """𝒟(C, G) = min_π Σ_i dist(c_i, g_π(i)) (Def. 3.1), with ρ_i.

    Complexity O(n³) (Jonker-Volgenant via ``linear_sum_assignment``); the cost matrix
    takes O(n²) memory (8 MB for n = 1000).

    Parameters
    ----------
    c, g:
        ``(n, 2)`` configurations of equal size.
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


def estimated_target(pattern: Pattern, leader: np.ndarray, followers: np.ndarray) -> np.ndarray:
    """𝒯^{φ_B}: ℙ on the leader, rotated so that B_P lies on the line L–B on B's side.

    (Sec. 4.2.) Returns NaNs when B = L (the axis is undefined, footnote 3).
    """
    leader = np.asarray(leader, dtype=float)
    to_leader = leader - np.asarray(followers, dtype=float).mean(axis=0)
    if np.linalg.norm(to_leader) == 0.0:
        return np.full_like(pattern.points, np.nan)
    return place(pattern.points, leader, rotation_onto(pattern.axis, to_leader))


def real_target(pattern: Pattern, leader: np.ndarray, heading: float) -> np.ndarray:
    """𝒯^{ψ_L}: ℙ on the leader, its x axis along the leader's heading ``ψ_L`` (Def. 3.2)."""
    c, s = np.cos(heading), np.sin(heading)
    return place(pattern.points, np.asarray(leader, dtype=float), np.array([[c, -s], [s, c]]))


def delta_series(positions: np.ndarray, headings: np.ndarray, pattern: Pattern) -> tuple[np.ndarray, np.ndarray]:
    """Δ_e(t) and Δ_r(t) (Sec. 4.2) for every sampled step.

    Parameters
    ----------
    positions:
        ``(T, 1 + m, 2)`` true positions, leader at index 0.
    headings:
        ``(T,)`` leader heading ψ_L(t) (radians).
    pattern:
        the pattern ℙ with ``m`` points.
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


def tail_start(n_samples: int) -> int:
    """Index of the first sample of the tail: the last :data:`TAIL_FRACTION` of the run (≥ 1 sample)."""
    return n_samples - max(1, int(n_samples * TAIL_FRACTION))


def formed_and_kept(values: np.ndarray, xi: float) -> bool:
    """Whether the formation is formed up to ξ and kept (Defs. 3.3-3.4 on the horizon).

    True when ``values ≤ xi`` at every sample of the tail (the last 10 % of the run,
    at least one sample), so the formation held from before the tail to the end.
    """
    return bool(np.all(np.asarray(values)[tail_start(len(values)):] <= xi))


def within_share(times: np.ndarray, values: np.ndarray, xi: float, since_fraction: float = 2 / 3) -> float:
    """Share of the samples with ``t ≥ since_fraction · t_end`` where ``values ≤ xi``."""
    times = np.asarray(times)
    late = times >= times.max() * since_fraction
    return float(np.mean(np.asarray(values)[late] <= xi))


def formation_results(times: np.ndarray, delta_e: np.ndarray, delta_r: np.ndarray, xi: float) -> dict:
    """Δ_e and Δ_r at the end and over the tail, their convergence times to ξ (Def. 3.4),
    ``success`` (:func:`formed_and_kept` on Δ_e) and the share of the last third with Δ_r ≤ ξ."""
    tail = tail_start(len(delta_e))
    te, tr = convergence_time(times, delta_e, xi), convergence_time(times, delta_r, xi)
    return {
        "success": formed_and_kept(delta_e, xi), "xi": float(xi),
        "delta_e_final": float(delta_e[-1]), "delta_r_final": float(delta_r[-1]),
        "delta_e_tail": float(np.nanmean(delta_e[tail:])), "delta_r_tail": float(np.nanmean(delta_r[tail:])),
        "convergence_time_e": te, "convergence_time_r": tr,
        "converged_e": bool(np.isfinite(te)), "converged_r": bool(np.isfinite(tr)),
        "delta_r_within_xi_last_third": within_share(times, delta_r, xi),
    }


def mirror_results(times: np.ndarray, delta_e: np.ndarray, delta_up_to_reflection: np.ndarray, xi: float) -> dict:
    """For a non-lb-symmetric pattern: results on Δ_e up to reflection, the distance to the
    nearer of ℙ and its mirror image, which followers without common chirality cannot tell
    apart (Sec. 6.4); the mirror image was formed when it is nearer than ℙ at the end."""
    nearer = np.asarray(delta_up_to_reflection)
    return {"delta_m_final": float(nearer[-1]), "convergence_time_m": convergence_time(times, nearer, xi),
            "formed_mirror_image": bool(nearer[-1] < delta_e[-1])}


def cycle_results(log: CycleLog, n_followers: int) -> dict:
    """Slot changes (Sec. 5.1, problem 3), cycle count and the share of Looks that saw a
    follower moving, from the cycle log."""
    return {"slot_changes": int(slot_changes(log.robot, log.slot, n_followers).sum()), "cycles": len(log),
            "seen_moving_share": float(np.mean(log.seen_moving > 0)) if len(log) else 0.0}


def measured_conditions(log: CycleLog, course: LeaderCourse, radius: float, speeds: np.ndarray, xi: float,
                        slot_speed: float) -> ConditionReport:
    """Conditions (1)-(4) of Sec. 3.2 on a run: v_L and ω_L of the course as driven, each
    follower's longest Move τ_f^M as logged (its cycle, the wait included), and condition
    (4) swept over the logged Move intervals with the slot speed v_L + ω_L R_P."""
    longest_move = np.zeros(len(speeds))
    np.maximum.at(longest_move, log.robot, log.t_end - log.t_look)
    return check_conditions(course.speed, course.max_turn_rate, radius, speeds, longest_move, xi,
                            cond4=condition4_max(log.t_look, log.t_end, slot_speed), on_violation="ignore")


def condition_results(report: ConditionReport) -> dict:
    """Conditions (1)-(4) of Sec. 3.2 as measured on a run, and the quantities they compare."""
    return {"v_leader": report.v_leader, "omega_leader": report.omega_leader, "slot_speed": report.slot_speed,
            "v_min": report.v_min, "sum_k": report.sum_k, "condition_4_max": report.cond4, **report.holds}


def run_results(times: np.ndarray, delta_e: np.ndarray, delta_r: np.ndarray, xi: float, log: CycleLog, n_followers: int,
                conditions: ConditionReport, delta_up_to_reflection: np.ndarray | None = None) -> dict:
    """Every per-run result of :data:`RESULTS` but the spec's names (pattern, algorithm, scheduler).

    Parameters
    ----------
    times, delta_e, delta_r:
        The sampling instants and Δ_e(t), Δ_r(t) at each (Sec. 4.2).
    xi:
        ξ of Def. 3.3.
    log, n_followers:
        The cycle log of the run and the number of followers m.
    conditions:
        Conditions (1)-(4) of Sec. 3.2 measured on the log.
    delta_up_to_reflection:
        For a non-lb-symmetric pattern, Δ_e to the nearer of ℙ and its mirror image (else ``None``).
    """
    out = {"n_followers": int(n_followers), **formation_results(times, delta_e, delta_r, xi),
           **cycle_results(log, n_followers), **condition_results(conditions)}
    if delta_up_to_reflection is not None:
        out.update(mirror_results(times, delta_e, delta_up_to_reflection, xi))
    return out
