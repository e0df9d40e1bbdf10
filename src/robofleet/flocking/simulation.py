"""The one loop of the flocking family: spec → world → sampled steps → :class:`Trace`.

:func:`simulate` resolves the seed (:func:`robofleet.core.rng.resolve_seed`), builds the
world (:func:`build_world`: the pattern, the followers' speeds, starts and local frames,
the leader's course and the Look-Compute-Move engine of :mod:`.schedulers`), then advances
the engine one sampling interval per step through :class:`~robofleet.core.recorder.Recorder`:
step ``k`` runs every cycle that starts in ``[t_k, t_{k+1})`` and records the state at
``t_{k+1}``. The run has no early stop: the approximate flocking problem (Def. 3.4) asks
that the formation be *kept*, which only the whole horizon shows.

Everything random (random patterns, speeds, starts, local frames, leader turns,
activations, cycle and move lengths, the algorithm's random choices) is drawn from
streams keyed by ``(seed, purpose)`` (:func:`robofleet.core.rng.keyed_generator`), so a
seed gives the same trace whatever the executor.

Trace layout: ``positions`` ``(T, 1 + m, 2)`` with the **leader at index 0** and the
followers at 1..m; ``time``, ``delta_e``, ``delta_r``, ``leader_heading`` are ``(T,)``;
``estimated_target`` ``(T, m, 2)`` holds the slots of the estimated target 𝒯^{φ_B(t)}
(Sec. 4.2); a non-lb-symmetric pattern adds ``delta_e_up_to_reflection`` ``(T,)``.
Events are the cycle log (``kind: "cycle"``, one per Look-Compute-Move cycle). The
per-run results are those of :data:`metrics.RESULTS <robofleet.flocking.metrics.RESULTS>`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.family import expect_spec
from ..core.recorder import Recorder
from ..core.rng import keyed_generator, resolve_seed
from ..core.trace import Trace
from . import metrics
from .leader import LeaderCourse, build_course, check_conditions, resolve_speeds
from .model import LocalFrames
from .patterns import Pattern
from .schedulers import LookComputeMove, sample_times
from .spec import AUTO_XI_FACTOR, Spec, check_followers, check_pattern


@dataclass(frozen=True)
class World:
    """Everything a run needs, drawn from one seed.

    Attributes
    ----------
    pattern:
        the pattern ℙ (drawn for ``kind: random``).
    speeds, starts, frames:
        the followers' speeds v_f, start positions and local frames.
    course:
        the leader's course; ``slot_speed`` = v_L + ω_L R_P.
    xi:
        ξ of Def. 3.3.
    times:
        the sampling instants.
    engine:
        the Look-Compute-Move engine, at time 0.
    mirror:
        the mirror image of ℙ for a non-lb-symmetric pattern, else ``None``.
    """

    pattern: Pattern
    speeds: np.ndarray
    starts: np.ndarray
    frames: LocalFrames
    course: LeaderCourse
    slot_speed: float
    xi: float
    times: np.ndarray
    engine: LookComputeMove
    mirror: Pattern | None


def build_world(spec: Spec, seed: int) -> World:
    """The world of ``spec`` for ``seed``: pattern, followers, leader course and engine.

    Checks what depends on the draw (one follower per slot, a pattern the algorithm can
    form, conditions (1)-(3) of Sec. 3.2 with the drawn speeds, acting as ``checks`` says).
    ``xi: auto`` is ``2 m (v_L + ω_L R_P) max τ^M``, twice the bound of condition (3).
    """
    source = spec.source
    pattern = spec.pattern.build(rng=keyed_generator(seed, "pattern"), source=source)
    m = check_followers(spec, pattern, source)
    check_pattern(spec, pattern, source)
    f = spec.followers
    speeds = np.asarray(f.speeds, float) if f.speeds else keyed_generator(seed, "speeds").uniform(f.speed_min, f.speed_max, m)
    starts_rng = keyed_generator(seed, "starts")
    starts = np.asarray(f.starts, float) if f.starts else starts_rng.uniform(0.0, f.area, (m, 2))
    leader_start = np.asarray(spec.leader.start, float) if spec.leader.start else starts_rng.uniform(0.0, f.area, 2)
    leader_rng = keyed_generator(seed, "leader")
    heading = spec.leader.heading if spec.leader.heading is not None else float(leader_rng.uniform(-np.pi, np.pi))
    algorithm = spec.algorithm.build()
    frames = LocalFrames.random(m, keyed_generator(seed, "frames"), algorithm.frames)
    v_leader, w_leader = resolve_speeds(spec.leader, speeds, pattern.radius)
    tau_max = spec.scheduler.move_time_max
    slot_speed = v_leader + w_leader * pattern.radius
    xi = AUTO_XI_FACTOR * m * slot_speed * tau_max if spec.xi == "auto" else float(spec.xi)
    check_conditions(v_leader, w_leader, pattern.radius, speeds, tau_max, xi, on_violation=spec.checks.conditions, source=source)
    course = build_course(spec.leader, speed=v_leader, turn_rate=w_leader, start=leader_start, heading=heading,
                          horizon=spec.duration + tau_max, rng=leader_rng)
    engine = LookComputeMove(algorithm, pattern, frames, starts, speeds, course, spec.scheduler, duration=spec.duration,
                             scheduler_rng=keyed_generator(seed, "scheduler"), algorithm_rng=keyed_generator(seed, "algorithm"))
    mirror = None if pattern.is_lb_symmetric else Pattern(pattern.mirrored(), pattern.name)
    return World(pattern, speeds, starts, frames, course, slot_speed, xi, sample_times(spec.duration, spec.sample_dt), engine, mirror)


def sample_state(world: World, k: int, followers: np.ndarray, leader: np.ndarray, heading: float) -> dict[str, np.ndarray]:
    """State row ``k``: positions (leader first), time, leader heading, Δ_e, Δ_r (Sec. 4.2),
    the estimated target's slots and, for a non-lb-symmetric pattern, Δ_e up to reflection."""
    positions = np.vstack([leader, followers])
    de, dr = metrics.delta_series(positions[None], np.array([heading]), world.pattern)
    row = {"positions": positions, "time": world.times[k], "leader_heading": heading, "delta_e": de[0], "delta_r": dr[0],
           "estimated_target": metrics.estimated_target(world.pattern, leader, followers)}
    if world.mirror is not None:
        de_mirror, _ = metrics.delta_series(positions[None], np.array([heading]), world.mirror)
        row["delta_e_up_to_reflection"] = np.fmin(de[0], de_mirror[0])
    return row


def declare_arrays(rec: Recorder, initial: dict[str, np.ndarray]) -> None:
    """The state arrays of :func:`sample_state`, row 0 being ``initial``."""
    for name, value in initial.items():
        rec.state(name, np.shape(value), initial=value)


def simulate(spec: Spec, seed: int | None = None, progress: bool = False) -> Trace:
    """Run a flocking scenario and return its :class:`~robofleet.core.trace.Trace`.

    Results (``trace.results``, :data:`metrics.RESULTS <robofleet.flocking.metrics.RESULTS>`):
    Δ_e and Δ_r at the end and over the last 10 % of the run, the convergence times to ξ
    (Def. 3.4), ``success`` (the estimated formation formed up to ξ and kept), slot changes,
    cycle counts, and the conditions (1)-(4) of Sec. 3.2 measured on the cycle log.

    Parameters
    ----------
    spec:
        The validated scenario.
    seed:
        The run's seed (``None``: a fresh one, recorded as ``trace.seed``).
    progress:
        Show a progress bar over the sampling steps.
    """
    expect_spec(spec, Spec, "flocking")  # input validation: a validated flocking scenario
    seed = resolve_seed(seed)
    world = build_world(spec, seed)
    engine, times = world.engine, world.times
    leader, headings = world.course.position(times), world.course.heading(times)
    m = engine.size
    rec = Recorder(len(times) - 1, 1 + m, label=f"flocking · {world.pattern.name} · {m} followers", progress=progress)
    declare_arrays(rec, sample_state(world, 0, engine.followers(times[0]), leader[0], headings[0]))

    def step(k: int) -> None:
        with rec.timed(k):
            ran = engine.advance(times[k + 1])
            followers = engine.followers(times[k + 1])
            if k + 1 == rec.max_steps:  # the cycles between the last sample and the end of the horizon
                ran += engine.finish()
        for c in range(engine.looks - ran, engine.looks):
            rec.event(k, "cycle", **engine.cycle_fields(c))
        rec.put_state(k + 1, **sample_state(world, k + 1, followers, leader[k + 1], headings[k + 1]))

    rec.run(step)
    return rec.trace("flocking", scenario=spec.scenario_name, seed=seed, metadata=run_metadata(spec, world),
                     results=run_results(spec, world, rec))


def run_results(spec: Spec, world: World, rec: Recorder) -> dict:
    """``trace.results``: the spec's names, then
    :func:`metrics.run_results <robofleet.flocking.metrics.run_results>` of the recorded run."""
    log = world.engine.log()
    conditions = metrics.measured_conditions(log, world.course, world.pattern.radius, world.speeds, world.xi, world.slot_speed)
    a = rec.arrays()
    return {"pattern": world.pattern.name, "algorithm": spec.algorithm.kind, "scheduler": spec.scheduler.kind,
            **metrics.run_results(a["time"], a["delta_e"], a["delta_r"], world.xi, log, world.engine.size, conditions,
                                  a.get("delta_e_up_to_reflection"))}


def run_metadata(spec: Spec, world: World) -> dict:
    """What the arrays need to be read: leader index, sampling, the pattern, speeds, frames,
    the leader's speed and turn rate, ξ, the algorithm and scheduler parameters."""
    return {
        "name": spec.name, "leader_index": 0, "dt": spec.sample_dt, "sample_dt": spec.sample_dt, "duration": spec.duration,
        "pattern": world.pattern.points.tolist(), "pattern_name": world.pattern.name,
        "speeds": world.speeds.tolist(),
        "frame_angle": world.frames.angle.tolist(), "frame_hand": world.frames.hand.tolist(),
        "leader_speed": world.course.speed, "leader_turn_rate": world.course.max_turn_rate, "xi": world.xi,
        "algorithm": spec.algorithm.model_dump(), "scheduler": spec.scheduler.model_dump(),
    }
