"""Goal checker: when a robot has reached its goal and whether it is home, shared by every
model, the simulation, the safety filter's users and the environment.

A robot *reaches* its goal when the estimate it navigates on (the environment: its true
position) lies within the goal tolerance, ``‖g − p‖ ≤ tol`` (:func:`within_goal`). The
simulation latches the first time (``arrived``: arrival step, travel time) and tracks
whether each robot is *home* (:class:`GoalChecker`):

* a robot becomes home at a step where its estimate is within the tolerance and it holds
  (is not stepping aside or on its way back from a yield);
* it stops being home when it leaves on a yield (:mod:`.yielding`).

A robot whose return from a yield ran out of time holds where it stands: it is not home
until its estimate is within the tolerance again. A run ends, and succeeds, only when every
robot is home (:meth:`GoalChecker.all_home`); ``arrived`` in the results is the share of
robots home at the end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


def within_goal(points: np.ndarray, goals: np.ndarray, tolerance: float) -> np.ndarray:
    """``(N,)``: ``‖g_i − p_i‖ ≤ tolerance``."""
    return goal_distances(points, goals) <= tolerance


def goal_distances(points: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """``(N,)``: ``‖g_i − p_i‖``, one compiled pass rounded as ``np.linalg.norm(goals −
    points, axis=1)`` rounds it (the squares summed in order)."""
    out = np.empty(len(points))
    _goal_distances(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(goals, dtype=np.float64), out)
    return out


@numba.njit(cache=True)
def _goal_distances(points, goals, out):
    for i in range(len(points)):
        out[i] = row_distance(goals, points, i)


@numba.njit(cache=True, inline="always")
def row_distance(x, y, i):
    """``‖x_i − y_i‖`` rounded as ``np.linalg.norm(x − y, axis=1)[i]`` rounds it: the squared
    differences summed in order, then the root (the same for ``y − x``: a difference and its
    negation have one square)."""
    total = 0.0
    for c in range(x.shape[1]):
        d = x[i, c] - y[i, c]
        total = d * d if c == 0 else total + d * d
    return np.sqrt(total)


@dataclass
class GoalChecker:
    """Per-robot arrival latch and home flag (module docstring)."""

    tolerance: float
    arrived: np.ndarray
    home: np.ndarray
    within: np.ndarray
    distance: np.ndarray  # this step's ‖g − p‖

    @classmethod
    def initial(cls, n: int, tolerance: float) -> GoalChecker:
        return cls(tolerance, np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool), np.full(n, np.inf))

    def observe(self, points: np.ndarray, goals: np.ndarray) -> np.ndarray:
        """This step's estimates: latch the arrivals (returned, updated in place); the
        distances to the goals are kept in ``distance``."""
        self.distance = goal_distances(points, goals)
        self.within = self.distance <= self.tolerance  # within_goal
        self.arrived |= self.within
        return self.arrived

    def settle(self, holding: np.ndarray | bool = True) -> None:
        """After this step's decisions: robots within the tolerance that hold are home;
        robots that do not hold (stepping aside, returning) are not."""
        self.home = (self.home | self.within) & holding

    def all_home(self) -> bool:
        """Whether every robot is home."""
        return bool(self.home.all())
