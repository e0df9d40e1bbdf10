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

The loop runs through :class:`~robofleet.core.recorder.Recorder`: steps 1–3, 7 and 8 of
step 0 are observed first (:meth:`SearchBatch.observe`); then recorder step ``k`` is
steps 4–6 of step ``k`` followed by steps 1–3, 7, 8 of step ``k + 1``
(:meth:`SearchBatch.advance`), until every run has stopped (early stop) or ``max_steps``
moves are spent. :func:`simulate` is the family's entry point (spec → trace, seed rule
of :mod:`robofleet.core.rng`); :func:`run_search` and :func:`run_search_batch` run resolved
:class:`SearchProblem` s without recording arrays.
"""

from __future__ import annotations

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
from .neighbours import Neighbours, collision_pairs, find_neighbours, no_neighbours
from .policy import RobotStreams, StepContext
from .random_baseline import RandomUnvisitedPolicy
from .sensing import SensingTables, build_sensing
from .spec import LABELS, Algorithm, Spec, border_vertices
from .step_kernels import advance_clocks, may_collide, sense_and_record
from .timing import MotionTiming, heading_change

SMALL_TEAM = 32
"""Teams up to this size check a move for collisions pair by pair (O(n²) per run)."""


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
        grid = p.grid
        N = self.R * self.n
        self.maps = RobotMaps(N, grid.n_vertices, len(p.targets))
        self.streams = RobotStreams(list(seeds), self.n)
        self.policy = make_policy(p, self.algorithm, N)
        self.pos = np.concatenate([q.starts for q in problems]).astype(np.intp)
        self.failures = np.concatenate([q.failures for q in problems])
        self.starts = [q.starts for q in problems]
        self.heading = np.zeros(N)  # read by trapezoidal rotation only
        self.alive = np.ones(N, dtype=bool)
        self.running = np.ones(self.R, dtype=bool)
        self.visited = np.zeros((self.R, grid.n_vertices), dtype=bool)
        self.time = np.zeros(self.R)
        self.steps = np.full(self.R, p.max_steps)
        self.stopped = np.zeros(N, dtype=bool)
        self.completed = np.zeros(self.R, dtype=bool)
        self.collisions = np.zeros(self.R, dtype=np.intp)
        self.obstacle_collisions = np.zeros(self.R, dtype=np.intp)
        self.rounds = np.zeros(self.R, dtype=np.intp)
        self.no_collisions = np.zeros(self.R, dtype=np.intp)
        self.no_collisions.flags.writeable = False
        timing = p.timing
        self.rc2 = (p.r_c + EPS) ** 2
        self.rso2 = (p.r_so + EPS) ** 2
        self.translate_seconds = float(timing.translation_time(grid.a))
        self.fixed_rotation = timing.rotation_mode == "fixed"
        self.step_seconds = timing.rotation_seconds + self.translate_seconds
        self.penalty = timing.collision_penalty_moves * timing.move_time(grid.a)
        self.record = recorder is not None
        self.rec = recorder if recorder is not None else Recorder(p.max_steps, N)
        self.run_of = np.arange(N) // self.n
        self.no_neighbours = no_neighbours(N, self.n)
        self.has_failures = bool((self.failures >= 0).any())
        self.active = self.alive.copy()
        self.neighbours = self.no_neighbours
        self.context = StepContext(grid, p.sensing, self.maps, self.streams, self.pos, self.heading, self.active,
                                   neighbours=self.neighbours)

    def event(self, step: int, kind: str, **info: Any) -> None:
        """Record an event (single recorded runs), stamped with the run's clock."""
        if self.record:
            self.rec.event(step, kind, time=float(self.time[0]), **info)

    # -- steps 1-3 ----------------------------------------------------------------------
    def sense(self, step: int, live: np.ndarray) -> None:
        """Steps 1–2 at each live robot's own vertex (:func:`.step_kernels.sense_and_record`):
        target sensing, a finder's broadcast to every live robot of its run, and obstacle
        sensing recorded in each robot's own map (sensed-inaccessible neighbours blocked,
        and visited in situation 2)."""
        p, maps = self.p, self.maps
        finder = sense_and_record(live, self.pos, self.n, self.visited, p.sensing.target_visible, maps.targets,
                                  p.grid.candidates, p.sensing.edge_sensed_ok, p.sensing.sensed_inaccessible,
                                  maps.layers, maps.touched, maps.dirty, maps.unchecked, p.situation == 2)
        if self.record and finder.max(initial=-1) >= 0:
            for t in np.flatnonzero(finder >= 0):
                self.event(step, "target_found", robot=int(finder[t]), target=int(t))

    def detect_failures(self, step: int, table: Neighbours, near: np.ndarray) -> None:
        """Step 3 failure information: live robots near a silent robot block its vertex.

        ``near (L,)``: the entries of ``table`` within ``r_c`` or ``r_so``.
        """
        owner = table.owner
        seen = near & self.alive[owner] & ~self.alive[table.peer]
        if not seen.any():
            return
        watchers, silent = owner[seen], table.peer[seen]
        if self.record:
            known = self.maps.test(2, watchers, self.pos[silent][:, None])[:, 0]
            for w, s in zip(watchers[~known], silent[~known]):
                self.event(step, "failure_detected", robot=int(w), failed=int(s))
        self.maps.set(2, watchers, self.pos[silent])
        if self.p.situation == 2:
            self.maps.set(0, watchers, self.pos[silent])

    def stop_reached(self, active: np.ndarray) -> np.ndarray:
        """Rules (3)/(4) per robot, on its own map (only active robots can stop)."""
        if self.p.situation == 1:
            done = self.maps.targets.all(axis=1)
        else:
            done = self.maps.frontier_empty()
        return done & active

    def stop_received(self, own: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Step 8: the active robots that a stop broadcast by the robots ``own`` ends.

        Situation 1: rule (3) speaks of the targets, which every robot of the run knows
        alike, so the stop ends the search of every robot of the run (the paper's step 8).
        Situation 2: the stop carries the stopper's map, closed under travellable edges
        (rule (4)); it ends the search of a receiver whose vertex that map holds as sensed
        and not blocked: the receiver's whole accessible component is then visited. In a
        connected grid that is every robot (the paper's step 8); a robot trapped in a
        pocket, whose map covers only the pocket, no longer ends the others' search.
        """
        R, n = self.R, self.n
        stoppers, receivers = own.reshape(R, n), active.reshape(R, n) & ~own.reshape(R, n)
        if self.p.situation == 1:
            return (receivers & stoppers.any(axis=1, keepdims=True)).ravel()
        runs, i, j = np.nonzero(receivers[:, :, None] & stoppers[:, None, :])
        heard = np.zeros(R * n, dtype=bool)
        if len(runs):
            receiver, stopper = runs * n + i, runs * n + j
            where = self.pos[receiver][:, None]
            covers = self.maps.test(3, stopper, where)[:, 0] & ~self.maps.test(2, stopper, where)[:, 0]
            heard[receiver[covers]] = True
        return heard

    def stop_robots(self, step: int, active: np.ndarray) -> np.ndarray:
        """Steps 7–8: robots whose stop rule fires, and the receivers their stop broadcast
        ends (:meth:`stop_received`), stop for good; a run ends — completed — once every
        working robot of it has stopped. Returns the robots still active."""
        own = self.stop_reached(active)
        if not own.any():
            return active
        heard = self.stop_received(own, active)
        if self.record:
            for r in np.flatnonzero(own | heard):
                self.event(step, "stop", robot=int(r), rule="own" if own[r] else "received")
        self.stopped |= own | heard
        stopped, working = self.stopped.reshape(self.R, self.n), self.alive.reshape(self.R, self.n)
        finished = self.running & stopped.any(axis=1) & ~(working & ~stopped).any(axis=1)
        self.completed |= finished
        self.steps[finished] = step
        self.running &= ~finished
        return self.alive & ~self.stopped & self.running[self.run_of]

    # -- step 6 -------------------------------------------------------------------------
    def move(self, step: int, choice: np.ndarray, rounds: np.ndarray) -> None:
        """Step 6: bump into unsensed obstacles, count collisions, advance the clocks."""
        p, grid = self.p, self.p.grid
        if not p.sensing.exact:
            choice = self.bump(step, choice)
        per_run = self.count_collisions(step, choice)
        if self.fixed_rotation:
            advance_clocks(self.pos, choice, self.running, rounds, per_run, self.n, p.timing.decision_seconds,
                           self.penalty, self.step_seconds, self.time, self.rounds)
        else:
            self.advance_turning_clocks(choice, rounds, per_run)
        self.pos = choice
        if self.record:
            self.rec.put_state(step + 1, positions=grid.points[self.pos], vertex=self.pos[:, None], time=self.time[0])

    def count_collisions(self, step: int, choice: np.ndarray) -> np.ndarray:
        """Collisions of the move per run (observer side), each recorded as an event."""
        per_run = self.no_collisions
        if self.n > 1 and self.may_collide(choice):
            pairs = collision_pairs(self.pos, choice, self.n, self.p.grid.n_vertices)
            pairs = pairs[self.running[pairs[:, 0]]]
            per_run = np.bincount(pairs[:, 0], minlength=self.R)
            for r, i, j in pairs:
                self.event(step, "collision", robots=[int(i), int(j)], vertex=int(choice[r * self.n + i]))
        self.collisions += per_run
        return per_run

    def advance_turning_clocks(self, choice: np.ndarray, rounds: np.ndarray, per_run: np.ndarray) -> None:
        """Trapezoidal rotation: each running run's clock advances by its choice rounds, its
        collision penalties and its slowest robot's turn and translation."""
        dt = self.p.timing.decision_seconds * rounds + self.penalty * per_run
        moving = choice != self.pos
        if moving.any():
            dt = dt + self.turn_and_translate(moving, choice)
        self.time += np.where(self.running, dt, 0.0)
        self.rounds += np.where(self.running, rounds, 0)

    def may_collide(self, choice: np.ndarray) -> bool:
        """Cheap pre-check: a repeated destination in a run, or a robot moving onto an occupied
        vertex (compiled pairwise scan for small teams, sorting for large ones)."""
        if self.n <= SMALL_TEAM:
            return may_collide(self.pos, choice, self.n)
        key = (np.arange(len(choice)) // self.n) * self.p.grid.n_vertices
        dest, here = key + choice, key + self.pos
        ordered = np.sort(dest)
        if (ordered[1:] == ordered[:-1]).any():
            return True
        return bool(np.isin(dest[choice != self.pos], here).any())

    def turn_and_translate(self, moving: np.ndarray, choice: np.ndarray) -> np.ndarray:
        """Per run: duration of its slowest robot (trapezoidal rotation to the edge, then translation)."""
        grid, timing = self.p.grid, self.p.timing
        vec = grid.points[choice[moving]] - grid.points[self.pos[moving]]
        new_heading = np.arctan2(vec[:, 1], vec[:, 0])
        turn = np.zeros(len(choice))
        turn[moving] = timing.rotation_time(heading_change(self.heading[moving], new_heading)) + self.translate_seconds
        self.heading[moving] = new_heading
        return turn.reshape(self.R, self.n).max(axis=1)

    def bump(self, step: int, choice: np.ndarray) -> np.ndarray:
        """Robots that take an edge blocked by an unsensed obstacle touch it and stay (it learns the vertex blocked)."""
        grid = self.p.grid
        moving = choice != self.pos
        truly_free = (grid.edge_ok[self.pos] & (grid.neighbours[self.pos] == choice[:, None])).any(axis=1)
        bumped = moving & ~truly_free
        if bumped.any():
            np.add.at(self.obstacle_collisions, np.flatnonzero(bumped) // self.n, 1)
            for r in np.flatnonzero(bumped):
                self.event(step, "obstacle_collision", robot=int(r), vertex=int(choice[r]))
            self.maps.set(2, np.flatnonzero(bumped), choice[bumped])
        return np.where(bumped, self.pos, choice)

    # -- the loop -----------------------------------------------------------------------
    def run(self) -> list[SearchOutcome]:
        """Observe step 0, then :meth:`advance` through the recorder until every run stopped."""
        if not self.observe(0):
            self.rec.run(self.advance)
        return [self.outcome(r) for r in range(self.R)]

    def advance(self, k: int) -> bool:
        """Steps 4–6 of step ``k`` (choose, move), then :meth:`observe` of step ``k + 1``;
        ``True`` when every run has stopped."""
        with self.rec.timed(k):
            ctx = self.context
            ctx.pos, ctx.heading, ctx.active, ctx.neighbours = self.pos, self.heading, self.active, self.neighbours
            choice, rounds = self.policy.choose(ctx)
            self.move(k, choice, rounds)
            return self.observe(k + 1)

    def observe(self, step: int) -> bool:
        """Failures, steps 1–3 (sensing, failure detection, map exchange) and the stop check
        of steps 7–8 at ``step``; keeps the links and active robots for the next choice.
        ``True`` when every run has stopped."""
        active = self.active  # alive, not stopped, of a running run (kept by stop_robots)
        if self.has_failures:
            self.fail_robots(step)
            active = self.alive & ~self.stopped & self.running[self.run_of]
        live = np.flatnonzero(active)
        table = self.no_neighbours
        if self.n > 1:
            table, near = find_neighbours(self.p.grid.points[self.pos], self.n, self.alive, self.rc2, self.rso2)
            if self.has_failures:
                self.detect_failures(step, table, near)
        self.sense(step, live)
        if self.policy.communicates and len(table.peer) and table.link.any():
            self.maps.exchange(table.owner[table.link], table.peer[table.link])
        self.active, self.neighbours = self.stop_robots(step, active), table
        return not self.running.any()

    def fail_robots(self, step: int) -> None:
        """Failure injection: a robot whose failure step is reached stops for good."""
        failing = (self.failures == step) & self.alive
        for r in np.flatnonzero(failing):
            self.event(step, "failure", robot=int(r), vertex=int(self.pos[r]))
        self.alive &= ~failing

    def outcome(self, r: int) -> SearchOutcome:
        """Run ``r``'s observer record turned into its results
        (:func:`metrics.run_results <robofleet.search.metrics.run_results>`)."""
        p = self.p
        mine = slice(r * self.n, (r + 1) * self.n)
        steps = int(self.steps[r])
        record = RunRecord(
            situation=p.situation, search_time=float(self.time[r]), completed=bool(self.completed[r]), steps=steps,
            found=self.maps.targets[mine].any(axis=0), visited=self.visited[r].copy(),
            reachable=p.grid.reachable_from(self.starts[r]) & p.grid.accessible, collisions=int(self.collisions[r]),
            obstacle_collisions=int(self.obstacle_collisions[r]), rounds=int(self.rounds[r]),
            failed_robots=int((~self.alive[mine]).sum()))
        return SearchOutcome(run_results(record, p.grid, p.r_st), record.visited, steps)


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
