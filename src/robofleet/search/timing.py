"""Motion timing of one step (Section 4.3, step 6, and Table 1).

"robi rotates to face to the chosen vertex and then moves straightly along the edge of
the grid. Robots apply the trapezoidal velocity profiles based on a and speed and
acceleration limits." All robots move simultaneously, so a step lasts as long as its
slowest robot, plus the time of the sequential choices of step 5.

Table 1 (simulation row, units of ``a = 1``): ``v_max = 0.32 /s`` and ``t_move = 5.75 s``
= 4.5 s translation + 1.25 s rotation. The acceleration is not listed; the default
``0.32 / 1.375 /s²`` is the value for which the trapezoidal profile over ``a = 1`` takes
exactly 4.5 s (``a / v + v / acc``). Rotation is ``fixed`` (1.25 s per move, as in the
paper's simulation) or ``trapezoidal`` over the heading change with the angular limits
below (defaults: a half turn takes 1.25 s).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from ..core.config import SpecModel


class MotionTiming(SpecModel):
    """Timing parameters (frozen, keyword-only)."""

    v_max: float = Field(0.32, gt=0, description="translation speed limit (Table 1)")
    accel: float = Field(0.32 / 1.375, gt=0, description="translation acceleration limit")
    rotation_mode: Literal["fixed", "trapezoidal"] = "fixed"
    rotation_seconds: float = Field(1.25, ge=0, description="rotation time per move in fixed mode (Table 1)")
    omega_max: float = Field(2 * math.pi / 1.25, gt=0, description="angular speed limit, rad/s")
    alpha_max: float = Field(4 * math.pi / 1.25**2, gt=0, description="angular acceleration limit, rad/s^2")
    decision_seconds: float = Field(0.1, ge=0, description="time of one round of sequential choices (step 5)")
    collision_penalty_moves: float = Field(1.0, ge=0, description="extra move times per collision (RU, LFP)")

    def translation_time(self, distance: float | np.ndarray) -> np.ndarray:
        """Trapezoidal-profile time to travel ``distance``."""
        return trapezoid_time(distance, self.v_max, self.accel)

    def rotation_time(self, angle: float | np.ndarray) -> np.ndarray:
        """Time to turn by ``|angle|`` radians (fixed per move, or trapezoidal)."""
        angle = np.abs(np.asarray(angle, dtype=float))
        if self.rotation_mode == "fixed":
            return np.full(angle.shape, self.rotation_seconds)
        return trapezoid_time(angle, self.omega_max, self.alpha_max)

    def move_time(self, a: float) -> float:
        """``t_move`` of one step in fixed mode: rotation plus translation over ``a`` (5.75 s by default)."""
        return float(self.rotation_time(np.pi) + self.translation_time(a))


def trapezoid_time(distance: float | np.ndarray, v_max: float, accel: float) -> np.ndarray:
    """Duration of a rest-to-rest trapezoidal velocity profile.

    ``d ≥ v²/acc``: accelerate, cruise, decelerate: ``t = d/v + v/acc``. Shorter moves use a
    triangular profile: ``t = 2 √(d/acc)``. Zero distance takes zero time.
    """
    d = np.abs(np.asarray(distance, dtype=float))
    full = d / v_max + v_max / accel
    short = 2.0 * np.sqrt(d / accel)
    return np.where(d >= v_max**2 / accel, full, short)


def heading_change(old_heading: np.ndarray, new_heading: np.ndarray) -> np.ndarray:
    """Smallest absolute angle between two headings, in ``[0, π]``."""
    return np.abs((np.asarray(new_heading) - np.asarray(old_heading) + np.pi) % (2 * np.pi) - np.pi)
