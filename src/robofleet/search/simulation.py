"""The synchronous search loop of Fig. 4 (steps 1–8), shared by the four algorithms.

One iteration ``k`` (all robots simultaneously, Section 4):

- 1\\. **Sense targets** within ``r_st``; a robot that finds one broadcasts its position (all
  robots learn it).
- 2\\. **Sense obstacles** within ``r_so``: the robot marks its vertex visited, its free
  neighbours discovered; in situation 2 a neighbour it senses inaccessible is recorded as
  visited. **Failure detection**: a robot that stops answering is detected by the robots
  within ``r_c`` (missing reply) or ``r_so`` (sensed body); its vertex becomes blocked in
  their maps (and visited in situation 2).
- 3\\. **Exchange maps** with communication neighbours (robots within ``r_c``).
- 7\\. **Stop check**: rule (3) in situation 1 (all targets known), rule (4) in situation 2 (no
  unvisited vertex in the robot's map); 8. a stopping robot **broadcasts the stop** (with
  its map in situation 2) and stops. The stop ends the search of every robot in situation
  1, and in situation 2 of every robot whose vertex the stopper's map covers — every robot
  of a connected grid, as in the paper; a robot trapped in a pocket cut off by obstacles
  ends only its own search (a deviation for grids the paper assumes away, Assumption 2.1
  with 3.1.3). The run ends, *completed*, once every working robot has stopped.
- 4–5\\. **Choose** (the policy: sequential rules (1)/(2), RU or LFP).
- 6\\. **Move**: rotate, then translate one edge with a trapezoidal profile; the step lasts as
  long as the slowest robot plus the choice rounds (:mod:`.timing`).

The loop also keeps observer-only records (true visits, collisions) that no robot reads.
Several independent runs (same area, same number of robots, their own seeds and starts)
can advance in lockstep as one batch: robot ``g`` is robot ``g % n`` of run ``g // n``,
robots of different runs never sense, hear or collide with each other, and every robot
draws from its own stream — so a run's result does not depend on its batch.

The loop is compiled (:mod:`.loop_kernels`, one phase per function there): steps 1–3, 7
and 8 of step 0 are observed first; then step ``k`` is steps 4–6 of step ``k`` followed by
steps 1–3, 7, 8 of step ``k + 1``, until every run has stopped (early stop) or
``max_steps`` moves are spent. :meth:`SearchBatch.run_block` runs a block of steps per
call — the steps of one block of the robots' random draws — and records it through
:class:`~robofleet.core.recorder.Recorder`. :func:`simulate` is the family's entry point (spec → trace, seed rule
of :mod:`robofleet.core.rng`); :func:`run_search` and :func:`run_search_batch` run resolved
:class:`SearchProblem` s without recording arrays.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from ..core import arguments
from ..core.errors import ConfigError
from ..core.family import expect_spec
from ..core.recorder import Recorder
from ..core.rng import keyed_generator, resolve_seed
from ..core.trace import Trace
from .decentralized import SequentialPolicy
from .grids import EPS, Grid
from .knowledge import RobotMaps
from .levy_flight import LevyFlightPolicy
from .metrics import RunRecord, run_results
from .loop_kernels import (EVENT_KINDS, FAILURE, FAILURE_DETECTED, LEVY, OBSTACLE_COLLISION, RANDOM_UNVISITED, SEQUENTIAL, STOP,
                           TARGET_FOUND, LoopParameters, LoopState, LoopTables, run_steps)
from .policy import RobotStreams
from .random_baseline import RandomUnvisitedPolicy
from .sensing import SensingTables, build_sensing
from .spec import LABELS, Algorithm, Spec, border_vertices
from .timing import MotionTiming


@dataclass(frozen=True)
class LevyParameters:
    """Parameters of the grid-adapted LFP (see :mod:`.levy_flight`)."""

    beta: float = 1.5
    turn_sigma: float = np.pi / 2
    repulsion: float = 1.0
    max_flight: int = 20


@dataclass(frozen=True, eq=False)
class SearchProblem:
    """A fully resolved search instance (grid, sensing tables, robots, targets)."""

    grid: Grid
    sensing: SensingTables
    targets: np.ndarray
    starts: np.ndarray
    situation: int
    r_so: float
    r_st: float
    r_c: float
    timing: MotionTiming
    failures: np.ndarray
    max_steps: int
    levy: LevyParameters = field(default_factory=LevyParameters)

    @property
    def n_robots(self) -> int:
        return len(self.starts)


@dataclass
class SearchOutcome:
    """Results of one run (:func:`metrics.run_results <robofleet.search.metrics.run_results>`),
    the vertices a robot stood on ``(V,)`` and the steps (moves) taken."""

    results: dict
    visited: np.ndarray
    steps: int


def make_policy(problem: SearchProblem, algorithm: Algorithm,
                n_total: int) -> SequentialPolicy | RandomUnvisitedPolicy | LevyFlightPolicy:
    """The choice policy of ``algorithm`` for ``n_total`` robots (all runs of a batch)."""
    if algorithm is Algorithm.PROPOSED:
        return SequentialPolicy(repulsion=True)
    if algorithm is Algorithm.RULE1:
        return SequentialPolicy(repulsion=False)
    if algorithm is Algorithm.RU:
        return RandomUnvisitedPolicy()
    lv = problem.levy
    return LevyFlightPolicy(n_total, beta=lv.beta, turn_sigma=lv.turn_sigma, repulsion=lv.repulsion,
                            max_flight=lv.max_flight, r_so=problem.r_so)


class SearchBatch:
    """State of ``R`` lockstep runs: true positions (observer) and per-robot knowledge (robots).

    The loop itself is compiled (:mod:`.loop_kernels`): :meth:`run` observes step 0, then
    hands the recorder blocks of steps, each running in one compiled call
    (:meth:`run_block`) on the random draws of one block of the robots' streams.
    ``recorder`` (single runs only) receives the positions, vertices and clock of every
    step and the events; without one the batch still steps through a bare
    :class:`~robofleet.core.recorder.Recorder` (the loop and its early stop).

    Parameters
    ----------
    problems : list[~robofleet.search.simulation.SearchProblem]
    algorithm : ~robofleet.search.spec.Algorithm
    seeds : list[int]
    recorder : ~robofleet.core.recorder.Recorder | None
    """

    def __init__(self, problems: list[SearchProblem], algorithm: Algorithm, seeds: list[int], recorder: Recorder | None = None):
        check_batch(problems, Algorithm(algorithm))
        if recorder is not None and len(problems) != 1:
            raise ConfigError(f"recorder: expected a single run to record, received a batch of {len(problems)}")
        p = problems[0]
        self.p = p
        self.algorithm = Algorithm(algorithm)
        self.R, self.n = len(problems), p.n_robots
        N = self.R * self.n
        self.maps = RobotMaps(N, p.grid.n_vertices, len(p.targets))
        self.streams = RobotStreams(list(seeds), self.n)
        self.policy = make_policy(p, self.algorithm, N)
        self.starts = [q.starts for q in problems]
        self.record = recorder is not None
        self.rec = recorder if recorder is not None else Recorder(p.max_steps, N)
        self.tables = loop_tables(p, np.concatenate([q.failures for q in problems]).astype(np.int64))
        self.parameters = loop_parameters(p, self.algorithm, self.policy, self.record, bool((self.tables.failures >= 0).any()))
        self.state = initial_state(problems, self.maps, self.policy)
        self.last_links = self.maps.last_links
        self.executed, self.finished = 0, False
        self.block, self.drawn_from, self.drawn_until = None, 0, 0

    def run(self) -> list[SearchOutcome]:
        """Observe step 0 and run the first block of steps, then the others through the
        recorder until every run stopped (none when step 0's observation ends them all)."""
        self.run_block(0)
        if self.executed:
            self.rec.run(self.step)
        return [self.outcome(r) for r in range(self.R)]

    def step(self, k: int) -> bool:
        """The recorder's step function: step ``k`` runs in the block that starts there or
        ran already in an earlier one; ``True`` at the step after which every run has stopped."""
        if k >= self.executed:
            self.run_block(k)
        return self.finished and k == self.executed - 1

    def run_block(self, k: int, stop: int | None = None) -> None:
        """Steps ``k …`` up to ``stop``, the end of the robots' current block of draws or of
        the step budget, in one compiled call (:func:`.loop_kernels.run_steps`), its rows and
        events recorded; the steps share the call's wall time equally in ``step_seconds``.
        Steps are taken in order: ``k`` is the first step not run yet."""
        t0 = time.perf_counter()
        if k >= self.drawn_until:  # the next block of draws, for steps k, k + 1, …
            self.block, self.drawn_from, self.drawn_until = self.draws(), k, k + self.streams.chunk
        u, z, flight = self.block
        stop = min(self.drawn_until, self.p.max_steps, self.p.max_steps if stop is None else stop)
        taken, self.last_links, events, times, vertices, clock = run_steps(self.tables, self.parameters, self.state, k, stop,
                                                                           self.last_links, u, z, flight, k - self.drawn_from)
        self.executed, self.finished = k + taken, not self.state.running.any()
        if self.record:
            self.record_rows(k, vertices[1:taken + 1], clock[1:taken + 1])
            self.record_events(events, times)
        if taken:
            self.rec["step_seconds"][k:k + taken] = (time.perf_counter() - t0) / taken

    def draws(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The next block of every robot's draws: uniforms ``(N, m)``, normals ``(N, m, 3)``
        and LFP flight lengths ``(N, m)`` (LFP draws the normals first, as its step did)."""
        if isinstance(self.policy, LevyFlightPolicy):
            z = self.streams.normal_block()
            return self.streams.uniform_block(), z, self.policy.flight_lengths(z)
        u = self.streams.uniform_block()
        return u, np.zeros((len(u), u.shape[1], 3)), np.zeros(u.shape, dtype=np.intp)

    def record_rows(self, k: int, vertices: np.ndarray, clock: np.ndarray) -> None:
        """The states after steps ``k, k + 1, …``: positions, vertices and the run's clock."""
        rows = slice(k + 1, k + 1 + len(vertices))
        self.rec["positions"][rows] = self.p.grid.points[vertices]
        self.rec["vertex"][rows] = vertices[:, :, None]
        self.rec["time"][rows] = clock[:, None, None]

    def record_events(self, events: np.ndarray, times: np.ndarray) -> None:
        """The event rows of the compiled loop (:data:`.loop_kernels.EVENT_KINDS`) as recorder events."""
        for (step, kind, a, b, c), clock in zip(events.tolist(), times.tolist()):
            self.rec.event(step, EVENT_KINDS[kind], time=clock, **event_fields(kind, a, b, c))

    def outcome(self, r: int) -> SearchOutcome:
        """Run ``r``'s observer record turned into its results
        (:func:`metrics.run_results <robofleet.search.metrics.run_results>`)."""
        p, s = self.p, self.state
        mine = slice(r * self.n, (r + 1) * self.n)
        steps = int(s.steps[r])
        record = RunRecord(
            situation=p.situation, search_time=float(s.time[r]), completed=bool(s.completed[r]), steps=steps,
            found=s.targets[mine].any(axis=0), visited=s.visited[r].copy(),
            reachable=p.grid.reachable_from(self.starts[r]) & p.grid.accessible, collisions=int(s.collisions[r]),
            obstacle_collisions=int(s.obstacle_collisions[r]), rounds=int(s.rounds[r]),
            failed_robots=int((~s.alive[mine]).sum()))
        return SearchOutcome(run_results(record, p.grid, p.r_st), record.visited, steps)


def event_fields(kind: int, a: int, b: int, c: int) -> dict:
    """The fields of an event row of the compiled loop (:data:`.loop_kernels.EVENT_KINDS`)."""
    if kind == FAILURE:
        return {"robot": a, "vertex": b}
    if kind == FAILURE_DETECTED:
        return {"robot": a, "failed": b}
    if kind == TARGET_FOUND:
        return {"robot": a, "target": b}
    if kind == STOP:
        return {"robot": a, "rule": "own" if b else "received"}
    if kind == OBSTACLE_COLLISION:
        return {"robot": a, "vertex": b}
    return {"robots": [a, b], "vertex": c}


def loop_tables(p: SearchProblem, failures: np.ndarray) -> LoopTables:
    """The read-only tables of the compiled loop for problem ``p`` and the batch's failure steps."""
    grid, sensing = p.grid, p.sensing
    words, masks = grid.candidate_words
    return LoopTables(grid.points, grid.candidates, grid.neighbours, grid.edge_ok, words, masks, sensing.edge_sensed_ok,
                      sensing.sensed_inaccessible, sensing.target_visible, grid.priority, grid.edge_units,
                      grid.edge_unit_headings, grid.edge_headings, sensing.wall_push, failures)


def loop_parameters(p: SearchProblem, algorithm: Algorithm, policy, record: bool, has_failures: bool) -> LoopParameters:
    """The scalars of the compiled loop: policy, ranges (squared, with the cell size of the
    neighbour search) and the step timing of :mod:`.timing`."""
    timing, a = p.timing, p.grid.a
    rc2, rso2 = (p.r_c + EPS) ** 2, (p.r_so + EPS) ** 2
    reach2 = max(rc2, rso2)
    cell = max(float(np.sqrt(reach2)) * (1 + 1e-9), 1e-12)  # cells no narrower than the range, rounding included
    translate, penalty = move_durations(timing, a)
    if algorithm is Algorithm.LFP:
        code, repulsion = LEVY, float(policy.repulsion)
    elif algorithm is Algorithm.RU:
        code, repulsion = RANDOM_UNVISITED, 0.0
    else:
        code, repulsion = SEQUENTIAL, 1.0 if policy.repulsion else 0.0
    return LoopParameters(
        n=p.n_robots, situation=p.situation, policy=code, repulsion=repulsion, communicates=policy.communicates,
        exact=p.sensing.exact, fixed_rotation=timing.rotation_mode == "fixed", has_failures=has_failures, record=record,
        rc2=rc2, rso2=rso2, cell=cell, reach2=reach2, decision_seconds=float(timing.decision_seconds),
        penalty=penalty, step_seconds=timing.rotation_seconds + translate,
        translate_seconds=translate, omega_max=float(timing.omega_max), alpha_max=float(timing.alpha_max),
        turn_threshold=timing.omega_max**2 / timing.alpha_max, turn_cruise=timing.omega_max / timing.alpha_max,
        turn_sigma=float(p.levy.turn_sigma), n_vertices=p.grid.n_vertices)


@lru_cache(maxsize=64)
def move_durations(timing: MotionTiming, a: float) -> tuple[float, float]:
    """Seconds of one edge's translation and of one collision's penalty (:mod:`.timing`)."""
    return float(timing.translation_time(a)), float(timing.collision_penalty_moves * timing.move_time(a))


def initial_state(problems: list[SearchProblem], maps: RobotMaps, policy) -> LoopState:
    """The state before step 0: robots alive and active at their starts, knowing nothing."""
    R, n, p = len(problems), problems[0].n_robots, problems[0]
    N = R * n
    lfp = isinstance(policy, LevyFlightPolicy)
    return LoopState(
        pos=np.concatenate([q.starts for q in problems]).astype(np.int64), heading=np.zeros(N), alive=np.ones(N, dtype=bool),
        stopped=np.zeros(N, dtype=bool), active=np.ones(N, dtype=bool), running=np.ones(R, dtype=bool),
        completed=np.zeros(R, dtype=bool), steps=np.full(R, p.max_steps, dtype=np.int64), time=np.zeros(R),
        rounds=np.zeros(R, dtype=np.int64), collisions=np.zeros(R, dtype=np.int64), obstacle_collisions=np.zeros(R, dtype=np.int64),
        visited=np.zeros((R, p.grid.n_vertices), dtype=bool), layers=maps.layers, targets=maps.targets, touched=maps.touched,
        dirty=maps.dirty, unchecked=maps.unchecked, open=maps.open,
        levy_heading=policy.heading if lfp else np.zeros(N), remaining=policy.remaining.astype(np.int64) if lfp else np.zeros(N, dtype=np.int64),
        started=np.zeros(1, dtype=bool))


def check_batch(problems: list[SearchProblem], algorithm: Algorithm) -> None:
    """Raise ``ConfigError`` for LFP in situation 2 or for runs that do not share one area."""
    if algorithm is Algorithm.LFP and problems[0].situation == 2:
        raise ConfigError("algorithm: expected proposed, rule1 or ru in situation 2 (LFP keeps no map for stop rule (4)), received 'lfp'")
    first = problems[0]
    for q in problems[1:]:
        if q.grid is not first.grid or q.sensing is not first.sensing or q.n_robots != first.n_robots or q.situation != first.situation:
            raise ConfigError("problems: expected runs on one grid with the same robots and targets, received a mixed batch")


def checked_algorithm(algorithm: Algorithm | str) -> Algorithm:
    """``algorithm`` as an :class:`Algorithm`, or a one-line :class:`ConfigError` (input validation)."""
    try:
        return Algorithm(algorithm)
    except ValueError:
        raise ConfigError(f"algorithm: expected one of {[a.value for a in Algorithm]}, received {algorithm!r}") from None


def run_search(problem: SearchProblem, algorithm: Algorithm | str, seed: int) -> SearchOutcome:
    """Simulate one search run of ``algorithm`` on ``problem`` with per-robot streams from ``seed``.

    Raises
    ------
    ConfigError
        For LFP in situation 2 (LFP keeps no map, so stop rule (4) has no meaning).
    """
    arguments.instance(problem, SearchProblem, "problem", "a SearchProblem (build_problem)")  # input validation
    return SearchBatch([problem], checked_algorithm(algorithm), [resolve_seed(seed)]).run()[0]


def run_search_batch(problems: list[SearchProblem], algorithm: Algorithm | str, seeds: list[int]) -> list[SearchOutcome]:
    """Simulate independent runs in lockstep (one numpy pass per step for all of them).

    ``problems[k]`` (same grid, sensing tables, robot count; its own starts and failures)
    runs with seed ``seeds[k]``; each outcome equals ``run_search(problems[k], algorithm,
    seeds[k])`` exactly. Nothing is recorded.
    """
    if len(problems) != len(seeds) or not problems:
        raise ConfigError(f"seeds: expected one seed per problem ({len(problems)}), received {len(seeds)}")
    return SearchBatch(problems, Algorithm(algorithm), [int(s) for s in seeds]).run()


# -- the family's entry point: spec -> problem -> recorded run -> Trace ---------------------
@lru_cache(maxsize=32)
def cached_sensing(grid: Grid, targets: tuple, r_so: float, r_st: float) -> SensingTables:
    """The sensing tables of a grid and target set (:func:`.sensing.build_sensing`, once per process)."""
    return build_sensing(grid, np.asarray(targets, dtype=float).reshape(-1, 2), r_so, r_st)


def start_vertices(spec: Spec, grid: Grid, seed: int) -> np.ndarray:
    """Start vertex ids (Assumption 2.2): the given starts, or distinct random border vertices
    drawn from the stream ``(seed, "search-starts")``."""
    if spec.robots.starts is not None:
        return grid.nearest_vertex(np.asarray(spec.robots.starts, dtype=float))[0]
    border = border_vertices(grid)
    return np.sort(keyed_generator(seed, "search-starts").choice(border, size=spec.robots.count, replace=False))


def failure_steps(spec: Spec, seed: int) -> np.ndarray:
    """Step at which each robot fails (``-1``: never): the listed failures, then the random
    ones drawn from the stream ``(seed, "search-failures")``."""
    failures = np.full(spec.robots.n, -1, dtype=np.intp)
    for f in spec.failures:
        failures[f.robot] = f.step
    rf = spec.random_failures
    if rf.count:
        rng = keyed_generator(seed, "search-failures")
        robots = rng.choice(spec.robots.n, size=rf.count, replace=False)
        failures[robots] = rng.integers(0, rf.within_steps, size=rf.count)
    return failures


def build_problem(spec: Spec, seed: int) -> SearchProblem:
    """Resolve a spec into a :class:`SearchProblem` for ``seed`` (start and failure draws included)."""
    grid = spec.built_grid()
    r = spec.ranges
    sensing = cached_sensing(grid, tuple(map(tuple, spec.targets)), r.r_so, r.r_st)
    return SearchProblem(grid, sensing, np.asarray(spec.targets, dtype=float).reshape(-1, 2), start_vertices(spec, grid, seed),
                         spec.situation, r.r_so, r.r_st, r.r_c, spec.timing, failure_steps(spec, seed), spec.max_steps,
                         LevyParameters(spec.levy.beta, spec.levy.turn_sigma, spec.levy.repulsion, spec.levy.max_flight))


def recorder_for(spec: Spec, problem: SearchProblem, progress: bool) -> Recorder:
    """A :class:`Recorder` with the search's arrays: ``positions (n, 2)`` true vertex
    coordinates, ``vertex (n, 1)`` ids and ``time (n, 1)`` seconds since the start."""
    n = problem.n_robots
    rec = Recorder(spec.max_steps, n, label=f"search · {LABELS[spec.algorithm]} · {n} robots", progress=progress)
    rec.state("positions", (n, 2), initial=problem.grid.points[problem.starts])
    rec.state("vertex", (n, 1), dtype=np.int64, fill=-1, initial=problem.starts[:, None])
    rec.state("time", (n, 1), initial=0.0)
    return rec


def run_metadata(spec: Spec, problem: SearchProblem, outcome: SearchOutcome) -> dict:
    """What the figures need beside the arrays: the grid, its accessible and visited
    vertices, the targets, the starts, the ranges and the assumption report."""
    grid = problem.grid
    return {
        "algorithm": spec.algorithm.value, "algorithm_label": LABELS[spec.algorithm], "situation": spec.situation,
        "grid": grid.kind.value, "a": grid.a, "ranges": spec.ranges.model_dump(), "radius": spec.ranges.r_rob,
        "targets": problem.targets.tolist(), "starts": problem.starts.tolist(), "grid_points": grid.points.tolist(),
        "accessible": grid.accessible.tolist(), "visited": outcome.visited.tolist(),
        "assumptions": spec.assumption_report().as_dict(),
    }


def simulate(spec: Spec, seed: int | None = None, progress: bool = False) -> Trace:
    """Run one search (Fig. 4, steps 1–8) and return its :class:`Trace`.

    Parameters
    ----------
    spec:
        A validated search scenario (:class:`spec.Spec <robofleet.search.spec.Spec>`).
    seed:
        ``None`` draws one (:func:`robofleet.core.rng.resolve_seed`); the start vertices,
        random failures and every robot's choices derive from it, and it is recorded as
        ``trace.seed``.
    progress:
        Show a progress bar over the steps.

    Returns
    -------
    Trace
        Arrays ``positions (n_steps + 1, n_robots, 2)``, ``vertex`` and ``time``
        ``(n_steps + 1, n_robots, 1)``, ``step_seconds``; events ``target_found``,
        ``failure``, ``failure_detected``, ``collision``, ``obstacle_collision``, ``stop``
        (each with the run's clock ``time``); results of
        :data:`metrics.RESULTS <robofleet.search.metrics.RESULTS>` and ``success``.
    """
    expect_spec(spec, Spec, "search")  # input validation: a validated search scenario
    seed = resolve_seed(seed)
    problem = build_problem(spec, seed)
    rec = recorder_for(spec, problem, progress)
    outcome = SearchBatch([problem], spec.algorithm, [seed], recorder=rec).run()[0]
    return rec.trace("search", scenario=spec.scenario_name, seed=seed, metadata=run_metadata(spec, problem, outcome),
                     results=outcome.results, workspace=problem.grid.workspace)
