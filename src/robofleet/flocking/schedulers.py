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
ASYNC runs of the basic, stripe, hula-hoop and randomized algorithms go through the
compiled loop of :mod:`.compiled` instead (O(m) per Look and Compute, the same trace bit
for bit; :func:`compiled_setup` says when), with the heap of next-Look times kept as
arrays and the scheduler's stream drawn in the same order.

:class:`LookComputeMove` is the engine, advanced one sampling interval at a time by the
family's loop (:func:`robofleet.flocking.simulation.simulate`, through the core
recorder); :func:`run` drives it on its own for hand-built configurations (tests,
benchmarks) and returns the sampled positions and the cycle log.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from ..core.errors import ConfigError, ScenarioError
from ..core.budget import check_allocation
from ..core.recorder import Recorder
from .basic import BasicAlgorithm
from .compiled import BASIC, HULA_HOOP, RANDOMIZED, STRIPE, heapify, next_events, point_at, run_events
from .hula_hoop import HulaHoopAlgorithm
from .leader import LeaderCourse
from .model import Algorithm, LocalFrames, look
from .patterns import Pattern
from .randomized import RandomizedAlgorithm
from .scheduler_spec import SchedulerSpec
from .stripe import StripeAlgorithm


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
FLOAT_COLUMNS = ("t_look", "t_end", "start", "destination", "end", "travel", "path_length")  # points take two columns


class _CycleStore:
    """The cycle log as growing column blocks: ``ints`` (robot, slot, seen_moving) and
    ``floats`` (t_look, t_end, start x y, destination x y, end x y, travel, path_length);
    rows ``0 .. count − 1`` are filled, by either engine."""

    def __init__(self, capacity: int = 1024):
        self.ints = np.zeros((capacity, len(INT_COLUMNS)), dtype=np.int64)
        self.floats = np.zeros((capacity, 10))
        self.count = 0

    def reserve(self, rows: int) -> None:
        """Room for ``rows`` more rows (capacity doubles)."""
        need = self.count + rows
        if need > len(self.ints):
            size = max(need, 2 * len(self.ints))
            self.ints = np.concatenate([self.ints, np.zeros((size - len(self.ints), self.ints.shape[1]), dtype=np.int64)])
            self.floats = np.concatenate([self.floats, np.zeros((size - len(self.floats), self.floats.shape[1]))])

    def append(self, robot: int, slot: int, seen_moving: int, t_look: float, t_end: float, start, destination, end,
               travel: float, path_length: float) -> None:
        self.reserve(1)
        self.ints[self.count] = (robot, slot, seen_moving)
        self.floats[self.count] = (t_look, t_end, *start, *destination, *end, travel, path_length)
        self.count += 1

    def columns(self) -> dict[str, np.ndarray]:
        """Every column of :class:`CycleLog`, rows in time order (copies)."""
        ints, floats = self.ints[:self.count], self.floats[:self.count]
        out = {name: ints[:, c].copy() for c, name in enumerate(INT_COLUMNS)}
        c = 0
        for name in FLOAT_COLUMNS:
            width = 2 if name in POINT_COLUMNS else 1
            out[name] = floats[:, c:c + width].copy() if width == 2 else floats[:, c].copy()
            c += width
        return out


@dataclass
class RunResult:
    """Sampled true positions (leader at index 0), leader headings and the cycle log."""

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray
    log: CycleLog
    looks: int


class _Motion:
    """Current Move of every follower: padded world paths, start time, speed, length ℓ,
    and where the Move ends (``rest``, for the compiled engine)."""

    def __init__(self, starts: np.ndarray, speeds: np.ndarray, points: int):
        m = len(starts)
        self.path = np.repeat(starts[:, None, :], points + 1, axis=1)
        self.cum = np.zeros((m, points + 1))
        self.t0 = np.zeros(m)
        self.travel = np.zeros(m)
        self.speed = speeds
        self.rows = np.arange(m)
        self.rest = np.array([point_at(self.path, self.cum, i, 0.0) for i in range(m)]).reshape(m, 2)

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
        self.rest[i] = point_at(self.path, self.cum, i, travel)


def _rigidity_draws(spec: SchedulerSpec, n: int, rng: np.random.Generator) -> list[float]:
    """η ~ U(``rigidity``, 1) for each of ``n`` Moves (A2); 1 for rigid moves (no draw)."""
    return [rng.uniform(spec.rigidity, 1.0) if spec.rigidity < 1.0 else 1.0 for _ in range(n)]


def _look_batches(spec: SchedulerSpec, m: int, duration: float, rng: np.random.Generator):
    """Yield ``(t, robots, taus, etas)``: who looks when, their cycle lengths and the η of
    their Moves. ASYNC uses a heap of next-Look times. The scheduler's stream is drawn in
    the order activations / τ, then η of each robot of the batch."""
    if spec.kind in ("fsync", "ssync"):
        for t in range(int(np.floor(duration)) + 1):
            if spec.kind == "fsync":
                yield float(t), np.arange(m), np.ones(m), _rigidity_draws(spec, m, rng)
                continue
            active = np.zeros(m, dtype=bool)
            while not active.any():
                active = rng.random(m) < spec.activation_probability
            yield float(t), np.flatnonzero(active), np.ones(active.sum()), _rigidity_draws(spec, int(active.sum()), rng)
        return
    heap = [(float(t), i) for i, t in enumerate(rng.uniform(0.0, spec.cycle_min, size=m))]
    heapq.heapify(heap)
    rigid = spec.rigidity >= 1.0
    while heap and heap[0][0] <= duration:
        t, i = heapq.heappop(heap)
        tau = float(rng.uniform(spec.cycle_min, spec.cycle_max))
        heapq.heappush(heap, (t + tau, i))
        yield t, (i,), (tau,), (1.0 if rigid else rng.uniform(spec.rigidity, 1.0),)


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


def path_length(world: np.ndarray) -> float:
    """Length of a world path ``(K + 1, 2)``: its segment lengths summed in order (the
    value the Move's cumulative lengths end with)."""
    gaps = np.diff(world, axis=0)
    return float(np.cumsum(np.sqrt(gaps[:, 0] * gaps[:, 0] + gaps[:, 1] * gaps[:, 1]))[-1])


@dataclass(frozen=True)
class CompiledSetup:
    """What :func:`robofleet.flocking.compiled.run_events` needs besides the state: the
    algorithm kind and parameters, the local-frame matrices, the pattern points, the
    pattern axis and the slot order F_0, F_1, F_2 (rows padded with −1)."""

    kind: int
    matrices: np.ndarray
    pattern_points: np.ndarray
    pattern_axis: np.ndarray
    slots: np.ndarray
    n_slots: np.ndarray
    axis_tolerance: float
    margin: float
    tie_tolerance: float


COMPILED_KINDS = {BasicAlgorithm: BASIC, StripeAlgorithm: STRIPE, HulaHoopAlgorithm: HULA_HOOP, RandomizedAlgorithm: RANDOMIZED}


def compiled_setup(algorithm: Algorithm, pattern: Pattern, spec: SchedulerSpec, frames: LocalFrames) -> CompiledSetup | None:
    """The compiled loop's inputs when it covers this run, else ``None``: ASYNC, one of the
    basic (paper ranking), stripe, hula-hoop or randomized algorithms (exactly these
    classes, not subclasses), and for the randomized one an lb-symmetric pattern."""
    kind = COMPILED_KINDS.get(type(algorithm))
    if spec.kind != "async" or kind is None or algorithm.ranking != "paper":
        return None
    if kind == RANDOMIZED and not pattern.is_lb_symmetric:
        return None
    order = algorithm.slot_order(pattern, pattern.points)
    slots = np.full((3, pattern.size), -1, dtype=np.int64)
    for j, ranked in enumerate(order):
        slots[j, :len(ranked)] = ranked
    return CompiledSetup(kind, np.ascontiguousarray(frames.matrices), np.ascontiguousarray(pattern.points, dtype=float),
                         np.ascontiguousarray(algorithm.pattern_axis(pattern), dtype=float), slots,
                         np.array([len(r) for r in order], dtype=np.int64), float(algorithm.axis_tolerance),
                         float(getattr(algorithm, "margin", 0.0)), float(getattr(algorithm, "tie_tolerance", 0.0)))


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
    compiled:
        Run ASYNC cycles of the algorithms :func:`compiled_setup` covers in the compiled
        loop of :mod:`.compiled` (bit-identical to the interpreted steps, which run
        otherwise, and for the events the compiled loop hands back).
    """

    def __init__(self, algorithm: Algorithm, pattern: Pattern, frames: LocalFrames, starts, speeds, course: LeaderCourse,
                 spec: SchedulerSpec, *, duration: float, scheduler_rng: np.random.Generator,
                 algorithm_rng: np.random.Generator, compiled: bool = True):
        starts, speeds = _check_inputs(pattern, frames, starts, speeds)
        if spec.min_move > spec.rigidity * speeds.min() * spec.move_time_min:
            raise ScenarioError("scheduler.min_move", f"δ_f <= rigidity · min speed · shortest Move = {spec.rigidity * speeds.min() * spec.move_time_min:.4g}", spec.min_move)
        self.algorithm, self.pattern, self.frames, self.course, self.spec = algorithm, pattern, frames, course, spec
        self.starts, self.speeds = starts, speeds
        self.scheduler_rng, self.algorithm_rng = scheduler_rng, algorithm_rng
        self.motion = _Motion(starts, speeds, getattr(algorithm, "path_points", 1))
        self.memory: list = [None] * len(starts)
        self.store = _CycleStore()
        self.looks = 0
        self.duration = duration
        self._compiled = compiled_setup(algorithm, pattern, spec, frames) if compiled else None
        if self._compiled is None:
            self._batches = _look_batches(spec, len(starts), duration, scheduler_rng)
            self._pending = next(self._batches, None)
        else:  # the heap of next-Look times of _look_batches, kept as arrays
            self._heap_t = scheduler_rng.uniform(0.0, spec.cycle_min, size=len(starts))
            self._heap_i = np.arange(len(starts), dtype=np.int64)
            heapify(self._heap_t, self._heap_i)

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
        if self._compiled is not None:
            while self._run_compiled(*self._async_events(until)):
                pass
            return self.looks - before
        while self._pending is not None and self._pending[0] < until:
            self._run_batch(*self._pending)
            self._pending = next(self._batches, None)
        return self.looks - before

    def _async_events(self, until: float, most: int = 4096) -> tuple[np.ndarray, ...]:
        """The next ASYNC events before ``until`` (at most ``most``): Look times, robots, τ, η.

        The draws are those :func:`_look_batches` makes, in the same order (τ, then η, per
        event): a block of uniform doubles is drawn, the heap uses what it needs, and the
        stream is then left exactly that many draws further on. A follower looks at most
        once per ``cycle_min`` (A1), which bounds the block.
        """
        spec, rng = self.spec, self.scheduler_rng
        span = min(until, self.duration) - self._heap_t.min()
        limit = int(min(most, self.size * (max(span, 0.0) // spec.cycle_min + 1)))
        state = rng.bit_generator.state
        draws = rng.random(limit * (1 if spec.rigidity >= 1.0 else 2))
        out = np.empty(limit), np.empty(limit, dtype=np.int64), np.empty(limit), np.empty(limit)
        n, used = next_events(self._heap_t, self._heap_i, draws, spec.cycle_min, spec.cycle_max, spec.rigidity,
                              self.duration, until, *out)
        rng.bit_generator.state = state
        rng.random(used)
        return tuple(column[:n] for column in out)

    def _run_compiled(self, times: np.ndarray, robots: np.ndarray, taus: np.ndarray, etas: np.ndarray) -> int:
        """Run these events in the compiled loop (the ones it hands back run interpreted);
        returns how many there were."""
        leaders = self.course.position(times)
        setup, motion, store = self._compiled, self.motion, self.store
        store.reserve(len(times))
        done = 0
        while done < len(times):
            ran = run_events(setup.kind, times[done:], robots[done:], taus[done:], etas[done:], leaders[done:],
                             motion.path, motion.cum, motion.t0, motion.travel, motion.speed, motion.rest, setup.matrices,
                             setup.pattern_points, setup.pattern_axis, setup.slots, setup.n_slots,
                             setup.axis_tolerance, setup.margin, setup.tie_tolerance, self.spec.min_move,
                             store.ints, store.floats, store.count)
            store.count += ran
            self.looks += ran
            done += ran
            if done < len(times):
                self._run_batch(float(times[done]), (int(robots[done]),), (float(taus[done]),), (float(etas[done]),))
                done += 1
        return len(times)

    def finish(self) -> int:
        """Run the cycles left before the end of the horizon; return how many ran."""
        return self.advance(np.inf)

    def _run_batch(self, t: float, robots, taus, etas) -> None:
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
        for (i, tau, world, slot), eta in zip(plans, etas):
            length = path_length(world)
            travel = min(length, max(spec.min_move, eta * speeds[i] * tau))
            motion.set(i, world, t, travel)
            self.store.append(i, slot, int(np.count_nonzero(np.delete(moving, i))), t, t + tau, followers[i], world[-1],
                              motion.position_of(i, t + tau), travel, length)
        self.looks += len(robots)

    def cycle_fields(self, c: int) -> dict:
        """Cycle ``c`` as event fields (``robot`` = follower index 1..m, leader being 0)."""
        (robot, slot, seen), f = self.store.ints[c], self.store.floats[c]
        return {
            "robot": int(robot) + 1, "t_look": float(f[0]), "t_end": float(f[1]),
            "start": f[2:4].tolist(), "destination": f[4:6].tolist(), "end": f[6:8].tolist(),
            "travel": float(f[8]), "path_length": float(f[9]), "slot": int(slot), "seen_moving": int(seen),
        }

    def log(self) -> CycleLog:
        """The cycles run so far as a :class:`CycleLog`."""
        return CycleLog(**self.store.columns())


def run(algorithm: Algorithm, pattern: Pattern, frames: LocalFrames, starts: np.ndarray, speeds: np.ndarray,
        course: LeaderCourse, spec: SchedulerSpec, *, duration: float, sample_dt: float = 1.0,
        scheduler_rng: np.random.Generator, algorithm_rng: np.random.Generator, progress: bool = False,
        compiled: bool = True) -> RunResult:
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
    compiled:
        as for :class:`LookComputeMove` (the same trace either way).
    """
    if not isinstance(course, LeaderCourse) or not isinstance(spec, SchedulerSpec):  # input validation
        raise ConfigError(f"course, spec: expected a LeaderCourse and a SchedulerSpec, received {type(course).__name__}, {type(spec).__name__}")
    engine = LookComputeMove(algorithm, pattern, frames, starts, speeds, course, spec, duration=duration,
                             scheduler_rng=scheduler_rng, algorithm_rng=algorithm_rng, compiled=compiled)
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
