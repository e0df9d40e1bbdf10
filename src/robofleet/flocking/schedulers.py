"""Look-Compute-Move schedulers: FSYNC, SSYNC and ASYNC (Sec. 2, assumptions A1-A3).

One event-driven engine runs all three; they differ only in *who looks when*:

* **FSYNC**: every follower looks at t = 0, 1, 2, ... and its Move lasts the round.
* **SSYNC**: at each integer time a random non-empty subset looks (each follower
  independently with ``activation_probability``, redrawn while empty); moves finish
  within the round.
* **ASYNC** (the paper's model): every follower runs its own cycles. A cycle lasts
  τ ~ U(``cycle_min``, ``cycle_max``): finite and bounded below (A1). Look and Compute take
  no time (A3): the Move starts at the Look instant and the next Look happens when the
  cycle ends. Followers are observed while they move (positions are interpolated along
  their paths at the Look time). A heap of next-Look times orders the events.

Moves (A2, non-rigid): in a cycle of length τ a follower of speed v_f travels along its
path at speed v_f for ℓ = min(``|path|``, max(δ_f, η v_f τ)), η ~ U(``rigidity``, 1), then
stands still until the cycle ends; so it always covers at least min(δ_f, ``|path|``), reaches
destinations closer than δ_f, and the distance covered is unpredictable when
``rigidity < 1``. ``rigidity = 1`` gives rigid moves (destination reached whenever
v_f τ allows).

The algorithm only ever receives :class:`~robofleet.flocking.model.Snapshot` s built by
:func:`~robofleet.flocking.model.look` and returns local paths, turned back into world
coordinates here. Per Look the engine costs O(m) vectorized work plus the algorithm.

:class:`LookComputeMove` is the engine, advanced one sampling interval at a time by the
family's loop (:func:`robofleet.flocking.simulation.simulate`, through the core
recorder); :func:`run` drives it on its own for hand-built configurations (tests,
benchmarks) and returns the sampled positions and the cycle log.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from ..core.errors import ConfigError, ScenarioError
from ..core.budget import check_allocation
from ..core.recorder import Recorder
from ..core.config import SpecModel
from .leader import LeaderCourse
from .model import Algorithm, LocalFrames, look
from .patterns import Pattern


class SchedulerSpec(SpecModel):
    """Scheduler parameters (time unit = one leader move, as in Sec. 4.2)."""

    kind: Literal["fsync", "ssync", "async"] = "async"
    activation_probability: float = Field(default=0.5, gt=0.0, le=1.0)
    cycle_min: float = Field(default=0.5, gt=0.0)
    cycle_max: float = Field(default=1.5, gt=0.0)
    rigidity: float = Field(default=1.0, gt=0.0, le=1.0)
    min_move: float = Field(default=0.01, gt=0.0)

    @model_validator(mode="after")
    def _bounds(self):
        if self.cycle_max < self.cycle_min:
            raise ScenarioError("cycle_max", f"a value >= cycle_min ({self.cycle_min})", self.cycle_max)
        return self

    @property
    def move_time_max(self) -> float:
        """Longest possible Move (max_j τ_f^M(j) of Sec. 3.2)."""
        return self.cycle_max if self.kind == "async" else 1.0

    @property
    def move_time_min(self) -> float:
        return self.cycle_min if self.kind == "async" else 1.0


@dataclass
class CycleLog:
    """One row per Look-Compute-Move cycle (arrays of equal length, time order)."""

    robot: np.ndarray
    t_look: np.ndarray
    t_end: np.ndarray
    start: np.ndarray        # (C, 2) world position at the Look
    destination: np.ndarray  # (C, 2) world destination computed
    end: np.ndarray          # (C, 2) where the Move stopped
    travel: np.ndarray       # ℓ, distance covered along the path
    path_length: np.ndarray  # length of the planned path
    slot: np.ndarray         # pattern index chosen (-1 = wait)
    seen_moving: np.ndarray  # other followers observed while moving at that Look

    def __len__(self) -> int:
        return len(self.robot)


INT_COLUMNS = ("robot", "slot", "seen_moving")
POINT_COLUMNS = ("start", "destination", "end")


@dataclass
class RunResult:
    """Sampled true positions (leader at index 0), leader headings and the cycle log."""

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray
    log: CycleLog
    looks: int


class _Motion:
    """Current Move of every follower: padded world paths, start time, speed, length ℓ."""

    def __init__(self, starts: np.ndarray, speeds: np.ndarray, points: int):
        m = len(starts)
        self.path = np.repeat(starts[:, None, :], points + 1, axis=1)
        self.cum = np.zeros((m, points + 1))
        self.t0 = np.zeros(m)
        self.travel = np.zeros(m)
        self.speed = speeds
        self.rows = np.arange(m)

    def positions(self, t: float) -> np.ndarray:
        """Every follower's position at time ``t`` (vectorized over followers)."""
        s = np.clip(self.speed * (t - self.t0), 0.0, self.travel)
        seg = np.count_nonzero(self.cum[:, 1:-1] < s[:, None], axis=1)
        a, b = self.path[self.rows, seg], self.path[self.rows, seg + 1]
        c0, c1 = self.cum[self.rows, seg], self.cum[self.rows, seg + 1]
        frac = np.where(c1 > c0, (s - c0) / np.where(c1 > c0, c1 - c0, 1.0), 0.0)
        return a + frac[:, None] * (b - a)

    def position_of(self, i: int, t: float) -> np.ndarray:
        """Position of follower ``i`` at time ``t``."""
        s = min(max(self.speed[i] * (t - self.t0[i]), 0.0), self.travel[i])
        cum, path = self.cum[i], self.path[i]
        seg = min(int(np.searchsorted(cum, s, side="left")), len(cum) - 1)
        seg = max(seg, 1)
        c0, c1 = cum[seg - 1], cum[seg]
        frac = (s - c0) / (c1 - c0) if c1 > c0 else 0.0
        return path[seg - 1] + frac * (path[seg] - path[seg - 1])

    def moving(self, t: float) -> np.ndarray:
        return (self.t0 < t) & (self.speed * (t - self.t0) < self.travel)

    def set(self, i: int, world_path: np.ndarray, t: float, travel: float) -> None:
        k = self.path.shape[1] - 1
        pad = np.concatenate([world_path, np.repeat(world_path[-1:], k + 1 - len(world_path), axis=0)])
        self.path[i] = pad
        self.cum[i] = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pad, axis=0), axis=1))])
        self.t0[i] = t
        self.travel[i] = travel


def _look_batches(spec: SchedulerSpec, m: int, duration: float, rng: np.random.Generator):
    """Yield ``(t, robots)``: who looks when. ASYNC uses a heap of next-Look times."""
    if spec.kind in ("fsync", "ssync"):
        for t in range(int(np.floor(duration)) + 1):
            if spec.kind == "fsync":
                yield float(t), np.arange(m), np.ones(m)
                continue
            active = np.zeros(m, dtype=bool)
            while not active.any():
                active = rng.random(m) < spec.activation_probability
            yield float(t), np.flatnonzero(active), np.ones(active.sum())
        return
    heap = [(float(t), i) for i, t in enumerate(rng.uniform(0.0, spec.cycle_min, size=m))]
    heapq.heapify(heap)
    while heap and heap[0][0] <= duration:
        t, i = heapq.heappop(heap)
        tau = float(rng.uniform(spec.cycle_min, spec.cycle_max))
        heapq.heappush(heap, (t + tau, i))
        yield t, np.array([i]), np.array([tau])


def _check_inputs(pattern: Pattern, frames: LocalFrames, starts, speeds) -> tuple[np.ndarray, np.ndarray]:
    """Shapes and values checked once at the public boundary of :func:`run`."""
    if not isinstance(pattern, Pattern) or not isinstance(frames, LocalFrames):
        raise ConfigError(f"pattern, frames: expected a Pattern and LocalFrames, received {type(pattern).__name__}, {type(frames).__name__}")
    starts = np.asarray(starts, dtype=float)
    speeds = np.asarray(speeds, dtype=float)
    m = pattern.size
    if starts.shape != (m, 2) or not np.all(np.isfinite(starts)):
        raise ConfigError(f"starts: expected finite ({m}, 2) follower positions (one per slot), received shape {starts.shape}")
    if speeds.shape != (m,) or not np.all(speeds > 0):
        raise ConfigError(f"speeds: expected {m} speeds > 0, received {speeds.tolist()}")
    if frames.angle.shape != (m,):
        raise ConfigError(f"frames: expected {m} local frames, received {frames.angle.shape[0]}")
    return starts, speeds


def sample_times(duration: float, sample_dt: float) -> np.ndarray:
    """The sampling instants ``0, sample_dt, 2 sample_dt, … ≤ duration`` (at least two)."""
    for name, value in (("duration", duration), ("sample_dt", sample_dt)):  # input validation
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) or not 0 < value < np.inf:
            raise ConfigError(f"{name}: expected a finite number > 0, received {value!r}")
    check_allocation(8 * (duration / sample_dt + 2), "number of samples (duration / sample_dt)", "duration")
    times = np.arange(0.0, duration + 1e-9, sample_dt)
    if len(times) < 2:
        raise ConfigError(f"duration: expected at least one sampling interval (≥ sample_dt = {sample_dt:g}), received {duration!r}")
    return times


class LookComputeMove:
    """The Look-Compute-Move engine of Sec. 2: who looks when, each Compute, each Move.

    The loop calls :meth:`advance` with each sampling instant in turn, reads
    :meth:`followers` there, and calls :meth:`finish` after the last one.

    Parameters
    ----------
    algorithm : ~robofleet.flocking.model.Algorithm
        The Compute step, the pattern ℙ and the followers' local frames.
    pattern, frames:
        The Compute step, the pattern ℙ and the followers' local frames.
    starts, speeds:
        ``(m, 2)`` initial world positions and ``(m,)`` speeds v_f > 0 of the followers.
    course:
        The leader's course (observed at every Look).
    spec:
        The scheduler (FSYNC, SSYNC or ASYNC; A1-A3 of Sec. 2 as in the module docstring).
    duration:
        Simulated time: no Look happens after it.
    scheduler_rng, algorithm_rng:
        Independent seeded streams (activations, cycle and move lengths / the algorithm's
        own random choices).
    """

    def __init__(self, algorithm: Algorithm, pattern: Pattern, frames: LocalFrames, starts, speeds, course: LeaderCourse,
                 spec: SchedulerSpec, *, duration: float, scheduler_rng: np.random.Generator,
                 algorithm_rng: np.random.Generator):
        starts, speeds = _check_inputs(pattern, frames, starts, speeds)
        if spec.min_move > spec.rigidity * speeds.min() * spec.move_time_min:
            raise ScenarioError("scheduler.min_move", f"δ_f <= rigidity · min speed · shortest Move = {spec.rigidity * speeds.min() * spec.move_time_min:.4g}", spec.min_move)
        self.algorithm, self.pattern, self.frames, self.course, self.spec = algorithm, pattern, frames, course, spec
        self.starts, self.speeds = starts, speeds
        self.scheduler_rng, self.algorithm_rng = scheduler_rng, algorithm_rng
        self.motion = _Motion(starts, speeds, getattr(algorithm, "path_points", 1))
        self.memory: list = [None] * len(starts)
        self.rows: dict[str, list] = {k: [] for k in CycleLog.__dataclass_fields__}
        self.looks = 0
        self._batches = _look_batches(spec, len(starts), duration, scheduler_rng)
        self._pending = next(self._batches, None)

    @property
    def size(self) -> int:
        """Number of followers m."""
        return len(self.starts)

    def followers(self, t: float) -> np.ndarray:
        """``(m, 2)`` world positions of the followers at time ``t`` (moving ones interpolated)."""
        return self.motion.positions(t)

    def advance(self, until: float) -> int:
        """Run every Look-Compute-Move cycle that starts before ``until``; return how many ran."""
        before = self.looks
        while self._pending is not None and self._pending[0] < until:
            self._run_batch(*self._pending)
            self._pending = next(self._batches, None)
        return self.looks - before

    def finish(self) -> int:
        """Run the cycles left before the end of the horizon; return how many ran."""
        return self.advance(np.inf)

    def _run_batch(self, t: float, robots: np.ndarray, taus: np.ndarray) -> None:
        """The followers ``robots`` Look at time ``t`` (the same instant), Compute, and start
        their Moves of cycle lengths ``taus`` (A2: ℓ = min(|path|, max(δ_f, η v_f τ)))."""
        spec, motion, frames, speeds = self.spec, self.motion, self.frames, self.speeds
        followers = motion.positions(t)
        leader = self.course.position(t)
        heading = np.array([np.cos(self.course.heading(t)), np.sin(self.course.heading(t))]) if self.algorithm.needs_heading else None
        moving = motion.moving(t)
        plans = []
        for i, tau in zip(robots, taus):
            snap = look(frames, i, leader, followers, heading=heading,
                        odometry_origin=self.starts[i] if self.algorithm.needs_memory else None, memory=self.memory[i])
            decision = self.algorithm.decide(snap, self.pattern, self.algorithm_rng)
            self.memory[i] = decision.memory
            world = np.concatenate([followers[i][None], frames.to_world(i, decision.path, followers[i])])
            plans.append((i, tau, world, decision.slot))
        rows = self.rows
        for i, tau, world, slot in plans:
            length = float(np.linalg.norm(np.diff(world, axis=0), axis=1).sum())
            eta = self.scheduler_rng.uniform(spec.rigidity, 1.0) if spec.rigidity < 1.0 else 1.0
            travel = min(length, max(spec.min_move, eta * speeds[i] * tau))
            motion.set(i, world, t, travel)
            rows["robot"].append(i); rows["t_look"].append(t); rows["t_end"].append(t + tau)
            rows["start"].append(followers[i]); rows["destination"].append(world[-1])
            rows["end"].append(motion.position_of(i, t + tau)); rows["travel"].append(travel)
            rows["path_length"].append(length); rows["slot"].append(slot)
            rows["seen_moving"].append(int(np.count_nonzero(np.delete(moving, i))))
        self.looks += len(robots)

    def cycle_fields(self, c: int) -> dict:
        """Cycle ``c`` as event fields (``robot`` = follower index 1..m, leader being 0)."""
        rows = self.rows
        return {
            "robot": int(rows["robot"][c]) + 1, "t_look": float(rows["t_look"][c]), "t_end": float(rows["t_end"][c]),
            "start": rows["start"][c].tolist(), "destination": rows["destination"][c].tolist(), "end": rows["end"][c].tolist(),
            "travel": float(rows["travel"][c]), "path_length": float(rows["path_length"][c]), "slot": int(rows["slot"][c]),
            "seen_moving": int(rows["seen_moving"][c]),
        }

    def log(self) -> CycleLog:
        """The cycles run so far as a :class:`CycleLog`."""
        return CycleLog(**{k: np.asarray(v, dtype=float).reshape(-1, 2) if k in POINT_COLUMNS
                           else np.asarray(v, dtype=int if k in INT_COLUMNS else float) for k, v in self.rows.items()})


def run(algorithm: Algorithm, pattern: Pattern, frames: LocalFrames, starts: np.ndarray, speeds: np.ndarray,
        course: LeaderCourse, spec: SchedulerSpec, *, duration: float, sample_dt: float = 1.0,
        scheduler_rng: np.random.Generator, algorithm_rng: np.random.Generator, progress: bool = False) -> RunResult:
    """Simulate followers running ``algorithm`` under scheduler ``spec`` behind ``course``.

    The same engine and sampling as a scenario run, without a scenario: for hand-built
    configurations.

    Returns the sampled positions ``(T, 1 + m, 2)`` (leader at index 0) and the cycle log.

    Parameters
    ----------
    starts:
        ``(m, 2)`` initial world positions of the followers; ``speeds``: ``(m,)`` v_f > 0.
    duration:
        simulated time; samples are taken every ``sample_dt``.
    scheduler_rng, algorithm_rng:
        independent seeded streams (activation and move lengths / the algorithm's own
        random choices).
    """
    if not isinstance(course, LeaderCourse) or not isinstance(spec, SchedulerSpec):  # input validation
        raise ConfigError(f"course, spec: expected a LeaderCourse and a SchedulerSpec, received {type(course).__name__}, {type(spec).__name__}")
    engine = LookComputeMove(algorithm, pattern, frames, starts, speeds, course, spec, duration=duration,
                             scheduler_rng=scheduler_rng, algorithm_rng=algorithm_rng)
    times = sample_times(duration, sample_dt)
    leader = course.position(times)
    rec = Recorder(len(times) - 1, 1 + engine.size, label="flocking", progress=progress)
    rec.state("positions", (1 + engine.size, 2), initial=np.vstack([leader[0], engine.followers(times[0])]))

    def step(k: int) -> None:
        engine.advance(times[k + 1])
        rec.put_state(k + 1, positions=np.vstack([leader[k + 1], engine.followers(times[k + 1])]))
        if k + 1 == rec.max_steps:
            engine.finish()

    rec.run(step)
    return RunResult(times, rec.arrays()["positions"], course.heading(times), engine.log(), engine.looks)
