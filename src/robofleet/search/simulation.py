"""The synchronous search loop of Fig. 4 (steps 1–8), shared by the four algorithms.

One iteration ``k`` (all robots simultaneously, Section 4):

1. **Sense targets** within ``r_st``; a robot that finds one broadcasts its position (all
   robots learn it).
2. **Sense obstacles** within ``r_so``: the robot marks its vertex visited, its free
   neighbours discovered; in situation 2 a neighbour it senses inaccessible is recorded as
   visited. **Failure detection**: a robot that stops answering is detected by the robots
   within ``r_c`` (missing reply) or ``r_so`` (sensed body); its vertex becomes blocked in
   their maps (and visited in situation 2).
3. **Exchange maps** with communication neighbours (robots within ``r_c``).
7. **Stop check**: rule (3) in situation 1 (all targets known), rule (4) in situation 2 (no
   unvisited vertex in the robot's map); 8. a stopping robot **broadcasts the stop** and the
   search ends.
4–5. **Choose** (the policy: sequential rules (1)/(2), RU or LFP).
6. **Move**: rotate, then translate one edge with a trapezoidal profile; the step lasts as
   long as the slowest robot plus the choice rounds (:mod:`.timing`).

The loop also keeps observer-only records (true visits, collisions) that no robot reads.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from .decentralized import SequentialPolicy
from .grids import EPS, Grid
from .knowledge import RobotMaps
from .levy_flight import LevyFlightPolicy
from .policy import RobotStreams, StepContext
from .random_baseline import RandomUnvisitedPolicy
from .sensing import SensingTables
from .timing import MotionTiming, heading_change


class Algorithm(str, Enum):
    """The four algorithms of Fig. 7."""

    PROPOSED = "proposed"  # rules (1), (2) & (3): this paper
    RULE1 = "rule1"  # rules (1) & (3): the 2016 algorithm [8]
    RU = "ru"  # random, unvisited first, collisions allowed [7]
    LFP = "lfp"  # Lévy flight with potential field [12]


LABELS = {
    Algorithm.PROPOSED: "(1),(2)&(3)",
    Algorithm.RULE1: "(1)&(3)",
    Algorithm.RU: "RU",
    Algorithm.LFP: "LFP",
}


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
    """Results of one run; ``vertices``/``times`` only when recorded."""

    results: dict
    visited: np.ndarray
    events: list = field(default_factory=list)
    vertices: np.ndarray | None = None
    times: np.ndarray | None = None


def make_policy(problem: SearchProblem, algorithm: Algorithm):
    """The choice policy of ``algorithm``."""
    if algorithm is Algorithm.PROPOSED:
        return SequentialPolicy(repulsion=True)
    if algorithm is Algorithm.RULE1:
        return SequentialPolicy(repulsion=False)
    if algorithm is Algorithm.RU:
        return RandomUnvisitedPolicy()
    lv = problem.levy
    return LevyFlightPolicy(problem.n_robots, beta=lv.beta, turn_sigma=lv.turn_sigma, repulsion=lv.repulsion,
                            max_flight=lv.max_flight, r_so=problem.r_so)


def collision_pairs(pos: np.ndarray, choice: np.ndarray) -> np.ndarray:
    """``(K, 2)`` robot pairs that collide in a move: same destination, or swapping along one edge."""
    same = choice[:, None] == choice[None, :]
    swap = (choice[:, None] == pos[None, :]) & (choice[None, :] == pos[:, None]) & (choice != pos)[:, None]
    hit = np.triu(same | swap, k=1)
    return np.argwhere(hit)


class SearchRun:
    """State of one run: true positions (observer) and per-robot knowledge (robots)."""

    def __init__(self, problem: SearchProblem, algorithm: Algorithm, seed: int, record: bool):
        self.p = problem
        self.algorithm = Algorithm(algorithm)
        n, grid = problem.n_robots, problem.grid
        self.maps = RobotMaps(n, grid.n_vertices, len(problem.targets))
        self.streams = RobotStreams(seed, n)
        self.policy = make_policy(problem, self.algorithm)
        self.pos = problem.starts.astype(np.intp).copy()
        self.heading = np.zeros(n)
        self.alive = np.ones(n, dtype=bool)
        self.visited = np.zeros(grid.n_vertices, dtype=bool)
        self.time = 0.0
        self.counts = {"collisions": 0, "obstacle_collisions": 0, "rounds": 0}
        self.n = n
        timing = problem.timing
        self.rc2 = (problem.r_c + EPS) ** 2
        self.rso2 = (problem.r_so + EPS) ** 2
        self.translate_seconds = float(timing.translation_time(grid.a))
        self.fixed_rotation = timing.rotation_mode == "fixed"
        self.step_seconds = timing.rotation_seconds + self.translate_seconds
        self.penalty = timing.collision_penalty_moves * timing.move_time(grid.a)
        self.step2_rows = problem.sensing.step2_rows(problem.situation)
        self.occupied = np.zeros(grid.n_vertices, dtype=bool)
        self.record = record
        self.events: list[dict] = []
        self.trail = [self.pos.copy()] if record else None
        self.clock = [0.0] if record else None

    def event(self, step: int, kind: str, **info) -> None:
        if self.record:
            self.events.append({"step": step, "kind": kind, "time": self.time, **info})

    # -- steps 1-3 ----------------------------------------------------------------------
    def sense(self, step: int, live: np.ndarray) -> None:
        """Steps 1–2: target and obstacle sensing at each live robot's own vertex."""
        p, maps = self.p, self.maps
        here = self.pos[live]
        self.visited[here] = True
        seen = p.sensing.target_visible[here]
        if seen.any():
            if self.record:
                new = seen.any(axis=0) & ~maps.targets.any(axis=0)
                for t in np.flatnonzero(new):
                    self.event(step, "target_found", robot=int(live[np.argmax(seen[:, t])]), target=int(t))
            maps.broadcast_targets(seen.any(axis=0), live)
        maps.layers[live] |= self.step2_rows[here]

    def detect_failures(self, step: int, dist_ok: np.ndarray) -> None:
        """Step 3 failure information: live robots near a silent robot block its vertex."""
        failed = ~self.alive
        if not failed.any():
            return
        watchers, silent = np.nonzero(dist_ok & self.alive[:, None] & failed[None, :])
        if len(watchers):
            known = self.maps.test(2, watchers, self.pos[silent][:, None])[:, 0]
            for w, s in zip(watchers[~known], silent[~known]):
                self.event(step, "failure_detected", robot=int(w), failed=int(s))
            self.maps.set(2, watchers, self.pos[silent])
            if self.p.situation == 2:
                self.maps.set(0, watchers, self.pos[silent])

    def stop_reached(self) -> np.ndarray:
        """Rules (3)/(4) per robot (only live robots can stop)."""
        if self.p.situation == 1:
            done = self.maps.targets.all(axis=1)
        else:
            done = self.maps.frontier_empty()
        return done & self.alive

    # -- step 6 -------------------------------------------------------------------------
    def move(self, step: int, choice: np.ndarray, rounds: int) -> None:
        """Step 6: bump into unsensed obstacles, count collisions, advance the clock."""
        p, grid = self.p, self.p.grid
        if not p.sensing.exact:
            choice = self.bump(step, choice)
        moving = choice != self.pos
        pairs = collision_pairs(self.pos, choice) if self.n > 1 and self.may_collide(choice) else ()
        for i, j in pairs:
            self.event(step, "collision", robots=[int(i), int(j)], vertex=int(choice[i]))
        self.counts["collisions"] += len(pairs)
        dt = p.timing.decision_seconds * rounds + self.penalty * len(pairs)
        if moving.any():
            if self.fixed_rotation:
                dt += self.step_seconds
                vec = grid.points[choice[moving]] - grid.points[self.pos[moving]]
                self.heading[moving] = np.arctan2(vec[:, 1], vec[:, 0])
            else:
                dt += self.turn_and_translate(moving, choice)
        self.time += dt
        self.counts["rounds"] += rounds
        self.pos = choice
        if self.record:
            self.trail.append(self.pos.copy())
            self.clock.append(self.time)

    def may_collide(self, choice: np.ndarray) -> bool:
        """Cheap pre-check: a repeated destination, or a robot moving onto an occupied vertex."""
        ordered = np.sort(choice)
        if (ordered[1:] == ordered[:-1]).any():
            return True
        self.occupied[self.pos] = True
        into = self.occupied[choice[choice != self.pos]].any()
        self.occupied[self.pos] = False
        return bool(into)

    def turn_and_translate(self, moving: np.ndarray, choice: np.ndarray) -> float:
        """Duration of the slowest robot: trapezoidal rotation to the edge, then translation."""
        grid, timing = self.p.grid, self.p.timing
        vec = grid.points[choice[moving]] - grid.points[self.pos[moving]]
        new_heading = np.arctan2(vec[:, 1], vec[:, 0])
        turn = timing.rotation_time(heading_change(self.heading[moving], new_heading))
        self.heading[moving] = new_heading
        return float(np.max(turn)) + self.translate_seconds

    def bump(self, step: int, choice: np.ndarray) -> np.ndarray:
        """Robots that take an edge blocked by an unsensed obstacle touch it and stay (it learns the vertex blocked)."""
        grid = self.p.grid
        moving = choice != self.pos
        truly_free = (grid.edge_ok[self.pos] & (grid.neighbours[self.pos] == choice[:, None])).any(axis=1)
        bumped = moving & ~truly_free
        for r in np.flatnonzero(bumped):
            self.counts["obstacle_collisions"] += 1
            self.event(step, "obstacle_collision", robot=int(r), vertex=int(choice[r]))
        if bumped.any():
            self.maps.set(2, np.flatnonzero(bumped), choice[bumped])
        return np.where(bumped, self.pos, choice)

    # -- the loop -----------------------------------------------------------------------
    def run(self) -> SearchOutcome:
        p = self.p
        steps, stopped_by = 0, -1
        everyone = np.arange(self.n)
        no_links = np.zeros((self.n, self.n), dtype=bool)
        has_failures = bool((p.failures >= 0).any())
        for step in range(p.max_steps + 1):
            steps = step
            if has_failures:
                self.fail_robots(step)
            live = everyone if self.alive.all() else np.flatnonzero(self.alive)
            links = sensed = no_links
            if self.n > 1:
                pts = p.grid.points[self.pos]
                diff = pts[:, None, :] - pts[None, :, :]
                d2 = np.einsum("ijd,ijd->ij", diff, diff)
                np.fill_diagonal(d2, np.inf)
                in_range = d2 <= self.rc2
                sensed = (d2 <= self.rso2) & self.alive[:, None]
                links = in_range & self.alive[:, None] & self.alive[None, :]
                if has_failures:
                    self.detect_failures(step, in_range | sensed)
            self.sense(step, live)
            if self.policy.communicates and links.any():
                self.maps.exchange(links)
            done = self.stop_reached()
            if done.any():
                stopped_by = int(np.argmax(done))
                self.event(step, "stop", robot=stopped_by)
                break
            if step == p.max_steps:
                break
            ctx = StepContext(p.grid, p.sensing, self.maps, self.streams, self.pos, self.heading, self.alive,
                              links, sensed, links | sensed)
            choice, rounds = self.policy.choose(ctx)
            self.move(step, choice, rounds)
        return self.outcome(steps, stopped_by)

    def fail_robots(self, step: int) -> None:
        """Failure injection: a robot whose failure step is reached stops for good."""
        failing = (self.p.failures == step) & self.alive
        for r in np.flatnonzero(failing):
            self.event(step, "failure", robot=int(r), vertex=int(self.pos[r]))
        self.alive &= ~failing

    def outcome(self, steps: int, stopped_by: int) -> SearchOutcome:
        p = self.p
        reachable = p.grid.reachable_from(p.starts) & p.grid.accessible
        found = self.maps.targets.any(axis=0)
        results = {
            "search_time": float(self.time),
            "completed": bool(stopped_by >= 0),
            "n_steps": int(steps),
            "found_targets": int(found.sum()),
            "n_targets": int(len(p.targets)),
            "visited_share": float(self.visited[reachable].mean()) if reachable.any() else 1.0,
            "collisions": int(self.counts["collisions"]),
            "obstacle_collisions": int(self.counts["obstacle_collisions"]),
            "mean_rounds": float(self.counts["rounds"] / max(steps, 1)),
            "failed_robots": int((~self.alive).sum()),
        }
        out = SearchOutcome(results, self.visited.copy(), self.events)
        if self.record:
            out.vertices = np.asarray(self.trail)
            out.times = np.asarray(self.clock)
        return out


def run_search(problem: SearchProblem, algorithm: Algorithm | str, seed: int, record: bool = False) -> SearchOutcome:
    """Simulate one search run of ``algorithm`` on ``problem`` with per-robot streams from ``seed``.

    Raises
    ------
    ConfigError
        For LFP in situation 2 (LFP keeps no map, so stop rule (4) has no meaning).
    """
    algorithm = Algorithm(algorithm)
    if algorithm is Algorithm.LFP and problem.situation == 2:
        from ..core.errors import ConfigError

        raise ConfigError("algorithm: expected proposed, rule1 or ru in situation 2 (LFP keeps no map for stop rule (4)), received 'lfp'")
    return SearchRun(problem, algorithm, int(seed), record).run()
