"""Scenario files of the flocking family (``family: flocking``) and :func:`simulate`.

A scenario fixes the pattern, the followers (count, speed range, start area), the leader
course, the scheduler, the algorithm, the horizon and ξ. Everything random (random
patterns, starts, speeds, local frames, leader turns, activations, move lengths, random
choices of the algorithm) is drawn from streams keyed by ``(seed, purpose)``
(:func:`robofleet.core.rng.keyed_generator`), so a seed gives the same trace whatever
the executor.

Trace layout: ``positions`` ``(T, 1 + m, 2)`` with the **leader at index 0** and the
followers at 1..m; ``delta_e``, ``delta_r``, ``leader_heading``, ``time`` are ``(T,)``;
events are the cycle log (``kind: "cycle"``, one per Look-Compute-Move cycle).
"""

from __future__ import annotations

import warnings
from typing import Literal, Union

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..core.errors import ScenarioError
from ..core.rng import RngLike, as_generator, keyed_generator
from ..core.trace import Trace
from ..core.config import SpecModel
from . import metrics
from .basic import BasicAlgorithm
from .hula_hoop import HulaHoopAlgorithm
from .knowledge import ChiralityAlgorithm, MemoryAlgorithm, ObservableHeadingAlgorithm, SharedAxesAlgorithm
from .leader import RandomTurnsLeader, ScriptedLeader, build_course, check_conditions, condition4_max, resolve_speeds
from .model import LocalFrames
from .patterns import Pattern, PatternKind, make_pattern, validate_points
from .randomized import RandomizedAlgorithm
from .schedulers import SchedulerSpec, run
from .stripe import StripeAlgorithm

ALGORITHMS = {
    "basic": BasicAlgorithm, "stripe": StripeAlgorithm, "hula_hoop": HulaHoopAlgorithm,
    "randomized": RandomizedAlgorithm, "observable_heading": ObservableHeadingAlgorithm,
    "memory": MemoryAlgorithm, "chirality": ChiralityAlgorithm, "shared_axes": SharedAxesAlgorithm,
}
AlgorithmKind = Literal["basic", "stripe", "hula_hoop", "randomized", "observable_heading", "memory", "chirality", "shared_axes"]
#: Algorithms that form any pattern (Sec. 6.2.3, 6.2.4, 6.4); the others need lb-symmetry.
ANY_PATTERN = {"randomized", "chirality", "shared_axes"}
HEADING_BASED = {"observable_heading", "memory"}
AUTO_XI_FACTOR = 2.0


class PatternSpec(SpecModel):
    """``kind``: wedge | line | spread (Fig. 8) | random (Sec. 4.2) | points | file."""

    kind: PatternKind = "wedge"
    points: list[list[float]] | None = None
    n_points: int | None = Field(default=None, ge=1)
    path: str | None = None

    @model_validator(mode="after")
    def _fields(self):
        if self.kind == "points" and self.points is None:
            raise ScenarioError("points", "a list of [x, y] points for kind 'points'", None)
        if self.kind == "file" and not self.path:
            raise ScenarioError("path", "a pattern file path for kind 'file'", None)
        if self.kind == "points":
            validate_points(self.points, field="points")
        return self


class FollowersSpec(SpecModel):
    """Followers: ``count`` (default: one per slot), speeds v_f ~ U(speed_min, speed_max)
    or explicit ``speeds``, starts uniform in an ``area`` × ``area`` square or explicit."""

    count: int | None = Field(default=None, ge=1)
    speed_min: float = 0.5
    speed_max: float = 5.0
    speeds: list[float] | None = None
    area: float = Field(default=512.0, gt=0)
    starts: list[list[float]] | None = None

    @field_validator("speed_min", "speed_max")
    @classmethod
    def _positive(cls, v):
        if not v > 0:
            raise ScenarioError("", "a speed > 0", v)
        return v

    @field_validator("speeds")
    @classmethod
    def _all_positive(cls, v):
        if v is not None:
            bad = [i for i, s in enumerate(v) if not s > 0]
            if bad:
                raise ScenarioError(str(bad[0]), "a speed > 0", v[bad[0]])
        return v

    @model_validator(mode="after")
    def _consistent(self):
        if self.speed_max < self.speed_min:
            raise ScenarioError("speed_max", f"a value >= speed_min ({self.speed_min})", self.speed_max)
        for name, arr in (("speeds", self.speeds), ("starts", self.starts)):
            if arr is not None and self.count is not None and len(arr) != self.count:
                raise ScenarioError(name, f"{self.count} entries (followers.count)", f"{len(arr)} entries")
        if self.starts is not None:
            pts = np.asarray(self.starts, dtype=float)
            if pts.ndim != 2 or pts.shape[1] != 2:
                raise ScenarioError("starts", "a list of [x, y] points", self.starts)
            gap = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
            np.fill_diagonal(gap, np.inf)
            if np.any(gap == 0):
                raise ScenarioError("starts", "distinct start positions (Sec. 4: a valid initial configuration)", self.starts)
        return self


class AlgorithmSpec(SpecModel):
    """The algorithm and its tolerances."""

    kind: AlgorithmKind = "basic"
    axis_tolerance: float = Field(default=0.5, gt=0)
    margin: float = Field(default=1e-3, ge=0)
    random_move: float = Field(default=1.0, gt=0)

    def build(self):
        """The algorithm object (frozen dataclass) with this spec's parameters."""
        cls = ALGORITHMS[self.kind]
        kwargs = {"axis_tolerance": self.axis_tolerance}
        if self.kind in ("stripe", "hula_hoop"):
            kwargs["margin"] = self.margin
        if self.kind == "randomized":
            kwargs["random_move"] = self.random_move
        return cls(**kwargs)


class ChecksSpec(SpecModel):
    """What to do on a violated condition of Sec. 3.2 or a pattern the algorithm cannot form."""

    conditions: Literal["warn", "error", "ignore"] = "warn"
    pattern: Literal["warn", "error", "ignore"] = "error"


class Spec(SpecModel):
    """A flocking scenario (see the module docstring)."""

    family: Literal["flocking"] = "flocking"
    name: str = "flocking"
    pattern: PatternSpec = Field(default_factory=PatternSpec)
    followers: FollowersSpec = Field(default_factory=FollowersSpec)
    leader: Union[RandomTurnsLeader, ScriptedLeader] = Field(default_factory=RandomTurnsLeader, discriminator="kind")
    scheduler: SchedulerSpec = Field(default_factory=SchedulerSpec)
    algorithm: AlgorithmSpec = Field(default_factory=AlgorithmSpec)
    duration: float = Field(default=1000.0, gt=0)
    sample_dt: float = Field(default=1.0, gt=0)
    xi: Union[float, Literal["auto"]] = "auto"
    checks: ChecksSpec = Field(default_factory=ChecksSpec)

    @field_validator("xi")
    @classmethod
    def _xi(cls, v):
        if v != "auto" and not v > 0:
            raise ScenarioError("", "ξ > 0 or 'auto'", v)
        return v

    @model_validator(mode="after")
    def _cross_checks(self):
        if self.pattern.kind in ("wedge", "line", "spread", "points"):
            pattern = make_pattern(self.pattern.kind, points=self.pattern.points)
            check_followers(self, pattern)
            check_pattern(self, pattern)
        return self


def check_followers(spec: Spec, pattern: Pattern, source: str | None = None) -> int:
    """Number of followers; exactly one per slot (Sec. 4: |ℙ| − 1 followers)."""
    f = spec.followers
    count = f.count if f.count is not None else len(f.speeds or f.starts or []) or pattern.size
    if count < pattern.size:
        raise ScenarioError("followers.count", f"at least as many followers as pattern slots ({pattern.size})", count, source=source)
    if count > pattern.size:
        raise ScenarioError("followers.count", f"one follower per pattern slot ({pattern.size})", count, source=source)
    return count


def check_pattern(spec: Spec, pattern: Pattern, source: str | None = None) -> None:
    """Whether the chosen algorithm can form ``pattern`` (Sec. 4.1, 6.2, 6.4)."""
    kind = spec.algorithm.kind
    reason = ""
    if kind in HEADING_BASED and not (pattern.is_directed and pattern.is_lb_symmetric):
        reason = "a pattern symmetric about its x axis (the leader's heading)"
    elif kind not in ANY_PATTERN:
        ok, reason = pattern.supported_by_basic()
    if not reason or spec.checks.pattern == "ignore":
        return
    message = f"algorithm {kind!r} needs {reason}; use 'randomized', 'chirality' or 'shared_axes'"
    if spec.checks.pattern == "error":
        raise ScenarioError("pattern", message, pattern.points.tolist(), source=source)
    warnings.warn(f"{source + ': ' if source else ''}pattern: {message}", UserWarning, stacklevel=3)


def _seed_int(seed: RngLike) -> int:
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return int(seed)
    return int(as_generator(seed).integers(2**63 - 1))


def simulate(spec: Spec, seed: RngLike = None, progress: bool = False) -> Trace:
    """Run a flocking scenario and return its :class:`~robofleet.core.trace.Trace`.

    Results (merged into ``trace.summary()``): Δ_e and Δ_r at the end and averaged over
    the last 10 % of the run, the convergence times to ξ (Def. 3.4), slot changes, cycle
    counts, and the conditions (1)-(4) of Sec. 3.2 measured on the cycle log.
    """
    source = spec.source
    s = _seed_int(seed)
    p = spec.pattern
    pattern = make_pattern(p.kind, points=p.points, n_points=p.n_points, path=p.path, rng=keyed_generator(s, "pattern"), source=source)
    m = check_followers(spec, pattern, source)
    check_pattern(spec, pattern, source)
    f = spec.followers
    speeds = np.asarray(f.speeds, float) if f.speeds else keyed_generator(s, "speeds").uniform(f.speed_min, f.speed_max, m)
    starts_rng = keyed_generator(s, "starts")
    starts = np.asarray(f.starts, float) if f.starts else starts_rng.uniform(0.0, f.area, (m, 2))
    leader_start = np.asarray(spec.leader.start, float) if spec.leader.start else starts_rng.uniform(0.0, f.area, 2)
    leader_rng = keyed_generator(s, "leader")
    heading = spec.leader.heading if spec.leader.heading is not None else float(leader_rng.uniform(-np.pi, np.pi))
    algorithm = spec.algorithm.build()
    frames = LocalFrames.random(m, keyed_generator(s, "frames"), algorithm.frames)

    v_leader, w_leader = resolve_speeds(spec.leader, speeds, pattern.radius)
    tau_max = spec.scheduler.move_time_max
    slot_speed = v_leader + w_leader * pattern.radius
    xi = AUTO_XI_FACTOR * m * slot_speed * tau_max if spec.xi == "auto" else float(spec.xi)
    check_conditions(v_leader, w_leader, pattern.radius, speeds, tau_max, xi, on_violation=spec.checks.conditions, source=source)
    course = build_course(spec.leader, speed=v_leader, turn_rate=w_leader, start=leader_start, heading=heading,
                          horizon=spec.duration + tau_max, rng=leader_rng)
    result = run(algorithm, pattern, frames, starts, speeds, course, spec.scheduler, duration=spec.duration,
                 sample_dt=spec.sample_dt, scheduler_rng=keyed_generator(s, "scheduler"),
                 algorithm_rng=keyed_generator(s, "algorithm"), progress=progress)
    return _trace(spec, s, pattern, speeds, frames, course, result, xi, slot_speed)


def _trace(spec, seed, pattern, speeds, frames, course, result, xi, slot_speed) -> Trace:
    log = result.log
    m = pattern.size
    de, dr = metrics.delta_series(result.positions, result.headings, pattern)
    tail = max(1, len(de) // 10)
    tau_measured = np.zeros(m)
    np.maximum.at(tau_measured, log.robot, log.t_end - log.t_look)
    cond = check_conditions(course.speed, course.max_turn_rate, pattern.radius, speeds, tau_measured, xi,
                            cond4=condition4_max(log.t_look, log.t_end, slot_speed), on_violation="ignore")
    changes = metrics.slot_changes(log.robot, log.slot, m)
    results = {
        "pattern": pattern.name, "algorithm": spec.algorithm.kind, "scheduler": spec.scheduler.kind,
        "n_followers": m, "xi": xi,
        "delta_e_final": float(de[-1]), "delta_r_final": float(dr[-1]),
        "delta_e_tail": float(np.nanmean(de[-tail:])), "delta_r_tail": float(np.nanmean(dr[-tail:])),
        "convergence_time_e": metrics.convergence_time(result.times, de, xi),
        "convergence_time_r": metrics.convergence_time(result.times, dr, xi),
        "slot_changes": int(changes.sum()), "cycles": len(log),
        "seen_moving_share": float(np.mean(log.seen_moving > 0)) if len(log) else 0.0,
        **{f"leader_{k}" if not k.startswith("condition") else k: v for k, v in cond.as_dict().items()},
    }
    arrays = {"positions": result.positions, "time": result.times, "delta_e": de, "delta_r": dr, "leader_heading": result.headings}
    if not pattern.is_lb_symmetric:
        # Without common chirality ℙ and its mirror image look the same to every follower
        # (a mirrored frame): report the distance to the nearer of the two as well.
        de_mirror, _ = metrics.delta_series(result.positions, result.headings, Pattern(pattern.mirrored(), pattern.name))
        dm = np.fmin(de, de_mirror)
        arrays["delta_e_up_to_reflection"] = dm
        results["delta_m_final"] = float(dm[-1])
        results["convergence_time_m"] = metrics.convergence_time(result.times, dm, xi)
        results["formed_mirror_image"] = bool(de_mirror[-1] < de[-1])
    results["converged_e"] = bool(np.isfinite(results["convergence_time_e"]))
    results["converged_r"] = bool(np.isfinite(results["convergence_time_r"]))
    metadata = {
        "family": "flocking", "name": spec.name, "seed": seed, "leader_index": 0, "dt": spec.sample_dt,
        "sample_dt": spec.sample_dt, "duration": spec.duration, "pattern": pattern.points.tolist(), "pattern_name": pattern.name,
        "speeds": speeds.tolist(), "frame_angle": frames.angle.tolist(), "frame_hand": frames.hand.tolist(),
        "leader_speed": course.speed, "leader_turn_rate": course.max_turn_rate, "xi": xi,
        "algorithm": spec.algorithm.model_dump(), "scheduler": spec.scheduler.model_dump(),
    }
    return Trace("flocking", arrays, log.as_events(spec.sample_dt), metadata, results)
