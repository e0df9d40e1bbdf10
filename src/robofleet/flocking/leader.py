"""The leader's course and the solvability conditions (1)-(4) of Sec. 3.2.

The leader acts independently of the followers (Sec. 2). Two courses:

* ``random_turns`` (Sec. 4.2): the leader always moves forward at ``speed`` v_L; at each
  move (one time unit) with probability ``turn_probability`` (1/20 in the paper) it starts
  turning left or right (fair coin) at angular speed ``turn_rate`` ω_L, or, if already
  turning, goes straight again. ``turn_probability: 0`` gives a straight course.
* ``scripted``: a list of segments ``{duration, turn_rate}`` (signed; > 0 turns left),
  then straight.

``"auto"`` speed / turn rate follow the paper's "leader's speed was determined in
accordance with the limitations stated in Section 3.2": v_L = 0.4 min_i v_{f_i} and
ω_L = 0.4 min_i v_{f_i} / R_P, so v_L + ω_L R_P = 0.8 min_i v_{f_i} and (1)-(2) hold.

Both courses are arcs of constant curvature between breakpoints, so positions and
headings are exact at any time (:meth:`LeaderCourse.position`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, Union

import numpy as np
from pydantic import Field, field_validator

from ..core.errors import ConfigError, ScenarioError, short_repr
from ..core.rng import RngLike, as_generator
from ..core.config import SpecModel

AUTO_SPEED_FRACTION = 0.4
AUTO_TURN_FRACTION = 0.4


class FlockingConditionWarning(UserWarning):
    """A condition of Sec. 3.2 does not hold for a scenario (``on_violation: warn``)."""


class TurnSegment(SpecModel):
    """One scripted segment: ``duration`` time units at signed ``turn_rate`` (rad / time unit)."""

    duration: float = Field(gt=0)
    turn_rate: float = 0.0


class RandomTurnsLeader(SpecModel):
    """Leader of Sec. 4.2: forward at ``speed``; random starts/stops of turns at ``turn_rate``."""

    kind: Literal["random_turns"] = "random_turns"
    speed: Union[float, Literal["auto"]] = "auto"
    turn_rate: Union[float, Literal["auto"]] = "auto"
    turn_probability: float = Field(default=0.05, ge=0.0, le=1.0)
    start: list[float] | None = None
    heading: float | None = None

    @field_validator("speed")
    @classmethod
    def _positive_speed(cls, v):
        if v != "auto" and not v > 0:
            raise ScenarioError("", "a speed > 0 or 'auto'", v)
        return v

    @field_validator("turn_rate")
    @classmethod
    def _non_negative_turn(cls, v):
        if v != "auto" and not v >= 0:
            raise ScenarioError("", "a turn rate >= 0 or 'auto'", v)
        return v


class ScriptedLeader(SpecModel):
    """A scripted leader path: straight or turning segments at constant ``speed``."""

    kind: Literal["scripted"] = "scripted"
    speed: float = Field(gt=0)
    segments: list[TurnSegment] = Field(default_factory=list)
    start: list[float] | None = None
    heading: float | None = None


LeaderSpec = Union[RandomTurnsLeader, ScriptedLeader]


@dataclass(frozen=True)
class LeaderCourse:
    """A course made of constant-curvature arcs.

    ``times[k]`` are breakpoints (``times[0] = 0``), ``points[k]`` and ``headings[k]`` the
    state there, ``omega[k]`` the turn rate on ``[times[k], times[k+1])`` (the last one
    also applies after the last breakpoint).
    """

    speed: float
    times: np.ndarray
    points: np.ndarray
    headings: np.ndarray
    omega: np.ndarray

    @classmethod
    def build(cls, start: np.ndarray | Sequence[float], heading: float, speed: float, durations: np.ndarray,
              omega: np.ndarray) -> "LeaderCourse":
        """Integrate the arcs exactly (vectorized over segments)."""
        durations, omega = np.asarray(durations, float), np.asarray(omega, float)
        turn = omega * durations
        headings = heading + np.concatenate([[0.0], np.cumsum(turn)])
        steps = _arc(headings[:-1], omega, speed, durations)
        points = np.asarray(start, float) + np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
        times = np.concatenate([[0.0], np.cumsum(durations)])
        return cls(float(speed), times, points, headings, np.append(omega, omega[-1] if len(omega) else 0.0))

    def _segment(self, t):
        t = np.asarray(t, dtype=float)
        idx = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 1)
        return idx, t - self.times[idx]

    def position(self, t: float | np.ndarray) -> np.ndarray:
        """Leader position at time(s) ``t`` (shape ``t.shape + (2,)``)."""
        idx, dt = self._segment(t)
        return self.points[idx] + _arc(self.headings[idx], self.omega[idx], self.speed, dt)

    def heading(self, t: float | np.ndarray) -> np.ndarray:
        """Leader heading ψ_L(t) in radians."""
        idx, dt = self._segment(t)
        return self.headings[idx] + self.omega[idx] * dt

    @property
    def max_turn_rate(self) -> float:
        """ω_L actually used by the course."""
        return float(np.abs(self.omega).max(initial=0.0))


def _arc(heading, omega, speed, dt) -> np.ndarray:
    """Displacement along an arc of turn rate ``omega`` for ``dt`` at ``speed``."""
    heading, omega, dt = np.broadcast_arrays(np.asarray(heading, float), np.asarray(omega, float), np.asarray(dt, float))
    straight = np.abs(omega) < 1e-12
    w = np.where(straight, 1.0, omega)
    dx = np.where(straight, speed * dt * np.cos(heading), speed / w * (np.sin(heading + w * dt) - np.sin(heading)))
    dy = np.where(straight, speed * dt * np.sin(heading), speed / w * (np.cos(heading) - np.cos(heading + w * dt)))
    return np.stack([dx, dy], -1)


def resolve_speeds(spec: LeaderSpec, follower_speeds: np.ndarray, pattern_radius: float) -> tuple[float, float]:
    """(v_L, ω_L): the spec's values, or the ``"auto"`` values of the module docstring."""
    vmin = float(np.min(follower_speeds))
    if isinstance(spec, ScriptedLeader):
        return spec.speed, max((abs(s.turn_rate) for s in spec.segments), default=0.0)
    v = AUTO_SPEED_FRACTION * vmin if spec.speed == "auto" else float(spec.speed)
    w = AUTO_TURN_FRACTION * vmin / pattern_radius if spec.turn_rate == "auto" else float(spec.turn_rate)
    return v, w


def build_course(spec: LeaderSpec, *, speed: float, turn_rate: float, start: np.ndarray | Sequence[float], heading: float,
                 horizon: float, rng: RngLike = None) -> LeaderCourse:
    """The leader course up to ``horizon`` time units (random turns drawn from ``rng``)."""
    if isinstance(spec, ScriptedLeader):
        durations = np.array([s.duration for s in spec.segments] + [max(horizon, 1.0)])
        omega = np.array([s.turn_rate for s in spec.segments] + [0.0])
        return LeaderCourse.build(start, heading, speed, durations, omega)
    gen = as_generator(rng)
    n = int(np.ceil(horizon)) + 1
    toggles = gen.random(n) < spec.turn_probability
    run = np.cumsum(toggles)                     # a new straight/turning run at each toggle
    signs = np.where(gen.random(n + 1) < 0.5, -1.0, 1.0)[run]
    omega = np.where(run % 2 == 1, signs * turn_rate, 0.0)
    return LeaderCourse.build(start, heading, speed, np.ones(n), omega)


@dataclass(frozen=True)
class ConditionReport:
    """The conditions of Sec. 3.2 for one scenario.

    ``tau_move_max[i]`` is the longest Move of follower i (a priori bound or measured);
    ``sum_k`` = Σ_i k^{f_i} with k^f = (v_L + ω_L R_P) max_j τ_f^M(j); ``cond4`` is
    max_t Σ_i (v_L + ω_L R_P) τ̄_{f_i}(t) when measured on a cycle log (else ``nan``).
    """

    v_leader: float
    omega_leader: float
    radius: float
    v_min: float
    sum_k: float
    xi: float
    cond4: float = float("nan")

    @property
    def slot_speed(self) -> float:
        """v_L + ω_L R_P, the largest speed of a slot (Fig. 2)."""
        return self.v_leader + self.omega_leader * self.radius

    @property
    def holds(self) -> dict[str, bool]:
        return {
            "condition_1": self.v_leader < self.v_min,
            "condition_2": self.slot_speed < self.v_min,
            "condition_3": self.sum_k <= self.xi,
            "condition_4": bool(np.isnan(self.cond4) or self.cond4 <= self.xi),
        }

    def violations(self) -> list[str]:
        """Human-readable descriptions of the violated conditions."""
        text = {
            "condition_1": f"(1) v_L < min v_f: {self.v_leader:.4g} < {self.v_min:.4g}",
            "condition_2": f"(2) v_L + ω_L·R_P < min v_f: {self.slot_speed:.4g} < {self.v_min:.4g}",
            "condition_3": f"(3) Σ k^f ≤ ξ: {self.sum_k:.4g} ≤ {self.xi:.4g}",
            "condition_4": f"(4) max_t Σ (v_L + ω_L·R_P) τ̄_f(t) ≤ ξ: {self.cond4:.4g} ≤ {self.xi:.4g}",
        }
        return [text[k] for k, ok in self.holds.items() if not ok]

    def as_dict(self) -> dict:
        return {"v_leader": self.v_leader, "omega_leader": self.omega_leader, "slot_speed": self.slot_speed,
                "v_min": self.v_min, "sum_k": self.sum_k, "xi": self.xi, "condition_4_max": self.cond4, **self.holds}


def check_conditions(v_leader: float, omega_leader: float, radius: float, speeds: np.ndarray | Sequence[float],
                     tau_move_max: float | np.ndarray | Sequence[float], xi: float, *,
                     cond4: float = float("nan"), on_violation: Literal["warn", "error", "ignore"] = "warn",
                     source: str | None = None) -> ConditionReport:
    """Compute conditions (1)-(4) of Sec. 3.2 and act on violations.

    ``on_violation="warn"`` issues a :class:`FlockingConditionWarning`, ``"error"`` raises
    :class:`ScenarioError` (field ``leader``), ``"ignore"`` only reports.
    """
    speeds, tau = checked_condition_inputs(v_leader, omega_leader, radius, speeds, tau_move_max, xi, on_violation)
    slot_speed = v_leader + omega_leader * radius
    report = ConditionReport(float(v_leader), float(omega_leader), float(radius), float(speeds.min()),
                             float(np.sum(slot_speed * tau)), float(xi), float(cond4))
    bad = report.violations()
    if bad and on_violation == "error":
        raise ScenarioError("leader", "a leader within the conditions of Sec. 3.2", "; ".join(bad), source=source)
    if bad and on_violation == "warn":
        where = f"{source}: " if source else ""
        warnings.warn(f"{where}leader violates Sec. 3.2 condition(s): " + "; ".join(bad), FlockingConditionWarning, stacklevel=3)
    return report


def checked_condition_inputs(v_leader, omega_leader, radius, speeds, tau_move_max, xi, on_violation) -> tuple[np.ndarray, np.ndarray]:
    """Input validation of :func:`check_conditions`: finite numbers (ξ > 0), at least one
    follower speed, move times that broadcast to the speeds; one-line :class:`ConfigError` s."""
    for name, value in (("v_leader", v_leader), ("omega_leader", omega_leader), ("radius", radius), ("xi", xi)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) or not np.isfinite(value):
            raise ConfigError(f"{name}: expected a finite number, received {short_repr(value)}")
    try:
        speeds = np.asarray(speeds, float)
        tau = np.broadcast_to(np.asarray(tau_move_max, float), speeds.shape)
    except (TypeError, ValueError):
        raise ConfigError(f"speeds, tau_move_max: expected numbers of broadcastable shapes, received {short_repr(speeds)}, {short_repr(tau_move_max)}") from None
    if speeds.ndim != 1 or len(speeds) == 0 or not np.all(np.isfinite(speeds)) or not np.all(np.isfinite(tau)):
        raise ConfigError(f"speeds: expected one finite speed per follower (at least one), received {short_repr(speeds.tolist())}")
    if on_violation not in ("warn", "error", "ignore"):
        raise ConfigError(f"on_violation: expected 'warn', 'error' or 'ignore', received {short_repr(on_violation)}")
    return speeds, tau


def condition4_max(starts: np.ndarray, ends: np.ndarray, slot_speed: float) -> float:
    """max_t Σ_i (v_L + ω_L R_P) τ̄_{f_i}(t) (condition (4)) from the Move intervals of a log.

    ``starts``/``ends``: begin and end times of every Move (all followers). τ̄_f(t) is the
    time since the start of the Move f executes at t (0 when f is not moving). The sum is
    piecewise linear and increasing between events, so its supremum is reached at the
    left limit of some Move end. Sweep over sorted events: O(E log E).
    """
    starts, ends = np.asarray(starts, float), np.asarray(ends, float)
    if len(starts) == 0:
        return 0.0
    times = np.concatenate([starts, ends])
    kind = np.concatenate([np.zeros(len(starts)), np.ones(len(ends))])  # starts first on ties
    d_count = np.concatenate([np.ones(len(starts)), -np.ones(len(ends))])
    d_sum = np.concatenate([starts, -starts])
    order = np.lexsort((kind, times))
    count, total = np.cumsum(d_count[order]), np.cumsum(d_sum[order])
    is_end = kind[order] == 1
    t = times[order][is_end]
    before = (count[is_end] + 1) * t - (total[is_end] + starts[order[is_end] - len(starts)])
    return float(slot_speed * before.max())
