"""Goal checker: when a robot has reached its goal, shared by every model, the simulation,
the safety filter's users and the environment.

A robot *reaches* its goal when the estimate it navigates on (the environment: its true
position) lies within the goal tolerance, ``‖g − p‖ ≤ tol`` (:func:`within_goal`);
the simulation latches the first time (:func:`latch_arrivals`), after which the robot
holds or yields (:mod:`.yielding`).
"""

from __future__ import annotations

import numpy as np


def within_goal(points: np.ndarray, goals: np.ndarray, tolerance: float) -> np.ndarray:
    """``(N,)``: ``‖g_i − p_i‖ ≤ tolerance``."""
    return np.linalg.norm(goals - points, axis=1) <= tolerance


def latch_arrivals(arrived: np.ndarray, points: np.ndarray, goals: np.ndarray, tolerance: float) -> np.ndarray:
    """``arrived`` with every robot now within the tolerance of its goal set, in place."""
    arrived |= within_goal(points, goals, tolerance)
    return arrived
