"""Scenario files of the flocking family (``family: flocking``): the validated :class:`Spec`.

A scenario fixes the pattern, the followers (count, speed range, start area), the leader
course (:mod:`.leader`), the scheduler (:mod:`.schedulers`), the algorithm, the horizon
and ξ::

    family: flocking
    pattern: {kind: wedge}                     # wedge | line | spread | random | points | file
    followers: {speed_min: 0.5, speed_max: 5.0, area: 512}
    leader: {kind: random_turns, speed: auto, turn_rate: auto, turn_probability: 0.05}
    scheduler: {kind: async, cycle_min: 0.5, cycle_max: 1.5, rigidity: 0.5, min_move: 0.01}
    algorithm: {kind: basic}
    duration: 1500                             # simulated time units (leader moves)
    sample_dt: 1.0
    xi: auto                                   # ξ of Def. 3.3, or a number

The robots move in the unbounded plane (Sec. 2): there is no workspace. The followers and
the leader start uniformly in the square ``[0, area]²`` (Sec. 4.2: a side of 512 units)
unless ``followers.starts`` / ``leader.start`` are given.

The checks of Sec. 4 that a spec can decide before it runs (one follower per slot, an
algorithm that can form the pattern) run at validation; a pattern drawn per seed
(``kind: random``) or read from a file is checked when the run starts.
"""

from __future__ import annotations

import warnings
from typing import Literal, Union

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator

from ..core.budget import RunSize
from ..core.config import SpecModel
from ..core.errors import ScenarioError
from ..core.rng import RngLike
from .basic import BasicAlgorithm
from .hula_hoop import HulaHoopAlgorithm
from .knowledge import ChiralityAlgorithm, MemoryAlgorithm, ObservableHeadingAlgorithm, SharedAxesAlgorithm
from .leader import RandomTurnsLeader, ScriptedLeader
from .patterns import Pattern, PatternKind, make_pattern, validate_points
from .randomized import RandomizedAlgorithm
from .scheduler_spec import SchedulerSpec
from .stripe import StripeAlgorithm

ALGORITHMS = {
    "basic": BasicAlgorithm, "stripe": StripeAlgorithm, "hula_hoop": HulaHoopAlgorithm,
    "randomized": RandomizedAlgorithm, "observable_heading": ObservableHeadingAlgorithm,
    "memory": MemoryAlgorithm, "chirality": ChiralityAlgorithm, "shared_axes": SharedAxesAlgorithm,
}
AlgorithmKind = Literal["basic", "stripe", "hula_hoop", "randomized", "observable_heading", "memory", "chirality", "shared_axes"]
#: Algorithms that form any pattern (Sec. 6.2.3, 6.2.4, 6.4); the others need lb-symmetry.
ANY_PATTERN = {"randomized", "chirality", "shared_axes"}
#: Algorithms that align the pattern's x axis with the leader's heading (Sec. 6.1, 6.3).
HEADING_BASED = {"observable_heading", "memory"}
#: ``xi: auto`` is this factor times Σ_i k^{f_i}, the bound of condition (3) of Sec. 3.2.
AUTO_XI_FACTOR = 2.0
#: Slots of the built-in patterns (Fig. 8).
BUILTIN_SIZES = {"wedge": 6, "line": 4, "spread": 10}
#: Memory of one logged Look-Compute-Move cycle (its event and its log row), for the budget.
CYCLE_BYTES = 1500
#: Algorithms whose ranking keeps the paper's form (``algorithm.ranking: paper`` only).
PAPER_RANKING_ONLY = {"stripe", "hula_hoop"}
#: Algorithms whose slots are ranked by the distance from L first (lines 12-13): they
#: cannot keep a follower on an on-axis slot that is not the nearest to L.
LEADER_DISTANCE_RANKED = set(ALGORITHMS) - {"stripe"}


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

    def build(self, rng: RngLike = None, source: str | None = None) -> Pattern:
        """The pattern ℙ (a ``random`` one drawn from ``rng``; a ``file`` read beside ``source``)."""
        return make_pattern(self.kind, points=self.points, n_points=self.n_points, path=self.path, rng=rng, source=source)


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

    @property
    def slowest_speed(self) -> float:
        """The smallest follower speed the spec allows: min of ``speeds``, else ``speed_min``."""
        return float(min(self.speeds)) if self.speeds else float(self.speed_min)


class AlgorithmSpec(SpecModel):
    """The algorithm, its tolerances and its ranking.

    ``ranking: axis_slot_nearest`` (beyond the paper, opt-in; default ``paper``): the
    followers of a crowded semi-space sent to the free on-axis slot are the ones nearest
    to it, not the ones nearest to the leader (:meth:`.basic.BasicAlgorithm.ranked`), so
    that patterns whose on-axis slot is not the nearest to the leader can be formed. Not
    with ``stripe`` (its ranking puts the axis slot last already) nor ``hula_hoop`` (its
    stable spaces follow the paper's ranking).
    """

    kind: AlgorithmKind = "basic"
    axis_tolerance: float = Field(default=0.5, gt=0)
    margin: float = Field(default=1e-3, ge=0)
    random_move: float = Field(default=1.0, gt=0)
    ranking: Literal["paper", "axis_slot_nearest"] = "paper"

    @model_validator(mode="after")
    def _ranking(self):
        if self.ranking != "paper" and self.kind in PAPER_RANKING_ONLY:
            raise ScenarioError("ranking", f"'paper' with algorithm {self.kind!r} (only the paper's ranking is defined for it)",
                                self.ranking)
        return self

    def build(self) -> BasicAlgorithm:
        """The algorithm object (frozen dataclass) with this spec's parameters."""
        cls = ALGORITHMS[self.kind]
        kwargs = {"axis_tolerance": self.axis_tolerance, "ranking": self.ranking}
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
        if self.duration < self.sample_dt:
            raise ScenarioError("duration", f"at least one sampling interval (≥ sample_dt = {self.sample_dt:g})", self.duration)
        if self.pattern.kind in ("wedge", "line", "spread", "points"):
            pattern = self.pattern.build()
            check_followers(self, pattern)
            check_pattern(self, pattern)
        return self

    # -- input validation: the pattern file, the memory budget (robofleet.core.budget) ----
    @model_validator(mode="after")
    def _pattern_file(self, info: ValidationInfo):
        """Read a pattern file now (beside the scenario file the validation context names),
        so that ``validate`` refuses what the run would; without a context it is read at the run."""
        context = info.context if isinstance(info.context, dict) else {}
        if self.pattern.kind == "file" and "source" in context:
            try:
                pattern = self.pattern.build(source=context["source"])
            except ScenarioError as exc:
                inner = ": ".join(p for p in (str(exc.source), exc.field) if p) if exc.source and exc.source != context["source"] else exc.field
                raise ScenarioError(f"pattern.path: {inner}" if not inner.startswith("pattern.path") else inner, exc.expected, exc.received) from None
            check_followers(self, pattern)
            check_pattern(self, pattern)
        return self

    def run_size(self) -> RunSize:
        """What a run holds: per sample and robot a position and an estimated-target slot,
        per sample five scalars, and one logged cycle (an event) per Look-Compute-Move cycle
        (ASYNC: at most one per ``cycle_min`` per follower; FSYNC/SSYNC: one per time unit)."""
        m = self.expected_followers()
        steps = int(self.duration / self.sample_dt + 1e-9)
        asynchronous = self.scheduler.kind == "async"
        period = self.scheduler.cycle_min if asynchronous else 1.0
        cycles = m * (int(self.duration / period) + 1)
        followers = self.followers_field()
        cycle_fields = f"{followers}, duration, scheduler.cycle_min, sample_dt" if asynchronous else f"{followers}, duration, sample_dt"
        return RunSize(steps, 1 + m, 32, "duration, sample_dt", followers, 40 * (steps + 1) + CYCLE_BYTES * cycles, "cycle log",
                       cycle_fields)

    def expected_followers(self) -> int:
        """The follower count as the fields give it: ``count``, else one per listed speed or
        start, else the pattern's slots (a random pattern: at most 8; a file: read later, 1)."""
        f, pattern = self.followers, self.pattern
        given = f.count or len(f.speeds or f.starts or [])
        if given:
            return given
        if pattern.kind == "points":
            return len(pattern.points)
        if pattern.kind == "random":
            return pattern.n_points or 8
        return BUILTIN_SIZES.get(pattern.kind, 1)

    def followers_field(self) -> str:
        """The field that gives :meth:`expected_followers` its value."""
        f, pattern = self.followers, self.pattern
        if f.count or f.speeds or f.starts:
            return "followers.count" if f.count else "followers.speeds" if f.speeds else "followers.starts"
        return {"points": "pattern.points", "random": "pattern.n_points", "file": "pattern.path"}.get(pattern.kind, "pattern.kind")


def check_followers(spec: Spec, pattern: Pattern, source: str | None = None) -> int:
    """Number of followers; exactly one per slot (Sec. 4: ``|ℙ| − 1`` followers)."""
    f = spec.followers
    count = f.count if f.count is not None else len(f.speeds or f.starts or []) or pattern.size
    if count < pattern.size:
        raise ScenarioError("followers.count", f"at least as many followers as pattern slots ({pattern.size})", count, source=source)
    if count > pattern.size:
        raise ScenarioError("followers.count", f"one follower per pattern slot ({pattern.size})", count, source=source)
    return count


def pattern_limitation(kind: str, pattern: Pattern) -> str:
    """Why algorithm ``kind`` cannot form ``pattern`` (Sec. 4.1, 6.1-6.4), or ``""`` if it can.

    The basic algorithm and its Sec. 5 variants need an lb-symmetric pattern with at most
    one point on the L-B axis; the heading-based variants need a pattern symmetric about
    its x axis; randomized, chirality and shared axes form any pattern.
    """
    if kind in HEADING_BASED and not (pattern.is_directed and pattern.is_lb_symmetric):
        return "a pattern symmetric about its x axis (the leader's heading)"
    if kind not in ANY_PATTERN:
        return pattern.supported_by_basic()[1]
    return ""


def ranking_limitation(algorithm: AlgorithmSpec, pattern: Pattern) -> str:
    """Why the paper's ranking cannot keep a follower on the pattern's on-axis slot
    (:meth:`.patterns.Pattern.axis_slot_ranked_ahead`), or ``""``: not with the stripe
    ranking (distance from Y first) nor with ``ranking: axis_slot_nearest``."""
    ahead = pattern.axis_slot_ranked_ahead()
    if not len(ahead) or algorithm.kind not in LEADER_DISTANCE_RANKED or algorithm.ranking != "paper":
        return ""
    axis = pattern.points[pattern.side == 0][0]
    others = pattern.size - pattern.n_on_axis
    return (f"the on-axis slot {np.round(axis, 3).tolist()} ({np.linalg.norm(axis):.4g} from the leader) is not nearer to the "
            f"leader than {len(ahead)} of the {others} off-axis slots: a follower approaching it is ranked among the side "
            "slots and sent back while another takes its place, so followers swap slots for ever")


def check_pattern(spec: Spec, pattern: Pattern, source: str | None = None) -> None:
    """Act on :func:`pattern_limitation` as ``checks.pattern`` says (error, warn or ignore)."""
    kind = spec.algorithm.kind
    reason = pattern_limitation(kind, pattern)
    if not reason or spec.checks.pattern == "ignore":
        return
    message = f"algorithm {kind!r} needs {reason}; use 'randomized', 'chirality' or 'shared_axes'"
    if spec.checks.pattern == "error":
        raise ScenarioError("pattern", message, pattern.points.tolist(), source=source)
    warnings.warn(f"{source + ': ' if source else ''}pattern: {message}", UserWarning, stacklevel=3)
