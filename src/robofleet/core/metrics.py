"""Run metrics computed from true positions (never from estimates).

Complexities are per step: pair checks use a k-d tree (O(N log N + K)), obstacle
distances O(N · E) for E obstacle edges.
"""

from __future__ import annotations

import numpy as np

from . import geometry
from .workspace import Workspace

CONTACT_TOL = 1e-7
"""Metres of overlap below which touching discs do not count as a collision: the models
allow ``‖p_i − p_j‖ = 2 r`` exactly, which floating point may land a hair below."""


MOTION_RESULTS: dict[str, str] = {
    "collisions": "distinct robot pairs that touched (true positions)",
    "obstacle_collisions": "distinct robots that touched an obstacle",
    "collision_steps": "robot-pair and robot-obstacle contacts summed over steps",
    "min_pair_distance": "smallest centre distance between two robots over the run [m]",
    "min_obstacle_distance": "smallest centre distance from a robot to an obstacle over the run [m]",
    "arrived": "share of robots that reached their goal",
    "makespan": "time until the last robot arrived [s] (NaN unless all arrived)",
    "mean_travel_time": "mean arrival time of the robots that arrived [s]",
    "median_step_seconds": "median compute time of one step of the whole team [s]",
}
"""The keys :func:`motion_summary` adds to a run's results, and their meaning."""


def pair_contacts(positions: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Robot–robot contacts over a run.

    Parameters
    ----------
    positions: ``(T, N, d)`` true positions.
    radius: robot radius; robots i and j collide at step t when ``‖p_i − p_j‖ < 2 r − CONTACT_TOL``.

    Returns
    -------
    contacts: int array ``(K, 3)`` of ``(step, i, j)`` with ``i < j``.
    min_distance: ``(T,)`` minimum pairwise centre distance per step (``inf`` for N < 2).
    """
    rows, mins = [], np.full(len(positions), np.inf)
    for t, pts in enumerate(positions):
        mins[t] = geometry.nearest_neighbour_distance(pts).min(initial=np.inf)
        if mins[t] < 2 * radius - CONTACT_TOL:
            pairs = geometry.close_pairs(pts, 2 * radius - CONTACT_TOL)
            rows.append(np.column_stack([np.full(len(pairs), t), pairs]))
    contacts = np.concatenate(rows) if rows else np.empty((0, 3), dtype=np.intp)
    return contacts.astype(np.intp), mins


def obstacle_contacts(positions: np.ndarray, radius: float, workspace: Workspace) -> tuple[np.ndarray, np.ndarray]:
    """Robot–obstacle contacts: ``(step, robot)`` rows with clearance ``< r − CONTACT_TOL``, and the per-step minimum distance."""
    if not workspace.obstacles:
        return np.empty((0, 2), dtype=np.intp), np.full(len(positions), np.inf)
    dist = workspace.obstacle_distance(positions)
    hits = np.argwhere(dist < radius - CONTACT_TOL)
    return hits.astype(np.intp), dist.min(axis=-1)


def arrival_steps(positions: np.ndarray, goals: np.ndarray, tolerance: float) -> np.ndarray:
    """First step at which each robot is within ``tolerance`` of its goal and stays there.

    Returns ``(N,)`` ints, ``-1`` for robots that have not arrived by the end.
    """
    err = np.linalg.norm(positions - goals[None], axis=-1)  # (T, N)
    within = err <= tolerance
    # a robot has arrived at step t when it is within tolerance from t to the end
    stays = np.flip(np.logical_and.accumulate(np.flip(within, 0), axis=0), 0)
    any_stay = stays.any(axis=0)
    first = np.argmax(stays, axis=0)
    return np.where(any_stay, first, -1)


def motion_summary(
    positions: np.ndarray,
    goals: np.ndarray,
    radius: float,
    dt: float,
    goal_tolerance: float,
    workspace: Workspace | None = None,
    step_seconds: np.ndarray | None = None,
    arrivals: np.ndarray | None = None,
) -> dict:
    """The standard summary of a continuous-motion run.

    Keys: ``success`` (all arrived, no collision), ``collisions`` (distinct robot pairs
    that touched), ``obstacle_collisions`` (distinct robots that touched an obstacle),
    ``collision_steps``, ``min_pair_distance`` and ``min_obstacle_distance`` (centre
    distances, over the whole run), ``arrived`` (share of robots), ``makespan`` and
    ``mean_travel_time`` (seconds; ``nan`` where undefined), ``median_step_seconds``.
    ``arrivals`` (per-robot arrival steps, ``-1`` = never) may be given by a simulation
    that decides arrival itself (e.g. robots that stop once their estimate is at the
    goal); otherwise :func:`arrival_steps` derives it from the positions.
    """
    contacts, min_pair = pair_contacts(positions, radius)
    obs_hits, min_obs = obstacle_contacts(positions, radius, workspace) if workspace else (np.empty((0, 2)), np.full(len(positions), np.inf))
    if arrivals is None:
        arrivals = arrival_steps(positions, goals, goal_tolerance)
    return contact_summary(contacts, min_pair, obs_hits, min_obs, arrivals, dt, step_seconds, len(positions) - 1)


def contact_summary(
    contacts: np.ndarray,
    min_pair: np.ndarray,
    obs_hits: np.ndarray,
    min_obs: np.ndarray,
    arrivals: np.ndarray,
    dt: float,
    step_seconds: np.ndarray | None,
    n_steps: int,
) -> dict:
    """:func:`motion_summary` from the contacts of every state (``pair_contacts`` rows
    ``(step, i, j)``, ``obstacle_contacts`` rows ``(step, robot)``, per-state minimum
    distances) and the arrival steps: the form a run that tallies contacts step by step
    (without keeping every state) uses."""
    arrived = arrivals >= 0
    n_pairs = len({(int(i), int(j)) for _, i, j in contacts})
    n_obs = len({int(r) for _, r in obs_hits})
    steps = np.asarray(step_seconds) if step_seconds is not None and len(step_seconds) else np.array([np.nan])
    return {
        "success": bool(arrived.all() and n_pairs == 0 and n_obs == 0),
        "collisions": n_pairs,
        "obstacle_collisions": n_obs,
        "collision_steps": int(len(contacts) + len(obs_hits)),
        "min_pair_distance": float(min_pair.min(initial=np.inf)),
        "min_obstacle_distance": float(min_obs.min(initial=np.inf)),
        "arrived": float(arrived.mean()) if len(arrived) else 1.0,
        "makespan": float(arrivals.max() * dt) if arrived.all() else float("nan"),
        "mean_travel_time": float(arrivals[arrived].mean() * dt) if arrived.any() else float("nan"),
        "median_step_seconds": float(np.median(steps)),
        "n_steps": int(n_steps),
        "n_robots": int(len(arrivals)),
    }
