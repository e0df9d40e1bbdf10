"""Scenario files of the ``search`` family: :class:`Spec` and :func:`simulate`.

A file looks like::

    family: search
    workspace: {rectangle: [0, 0, 12, 10], obstacles: [[[3, 3], [5, 3], [5, 5], [3, 5]]]}
    grid: {kind: triangular, a: 1.0}
    ranges: {r_rob: 0.26, r_safe: 0.31, r_so: 1.31, r_st: 1.31, r_c: 2.05}   # Table 1
    algorithm: proposed          # proposed | rule1 | ru | lfp
    situation: 1                 # 1: number of targets known, 2: search everything
    targets: [[2, 2], [6, 8]]
    robots: {count: 3}           # random border vertices per seed, or starts: [[x, y], ...]
    failures: [{robot: 1, step: 10}]
    require_guarantee: false     # true: every assumption must hold (else an error)

Obstacles are unknown to the robots: the simulation gives them only what they sense.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Literal

import numpy as np
import shapely
from pydantic import Field, field_validator, model_validator

from ..core.errors import ConfigError, ScenarioError
from ..core.geometry import ensure_ccw
from ..core.rng import RngLike, as_generator, keyed_generator
from ..core.trace import Trace
from ..core.workspace import Workspace
from ..core.config import SpecModel
from .assumptions import AssumptionReport, check_assumptions
from .coverage import CoverageProbe
from .grids import Grid, GridKind, build_grid
from .sensing import build_sensing
from .simulation import LABELS, Algorithm, LevyParameters, SearchProblem, run_search
from .timing import MotionTiming

Point = tuple[float, float]


class WorkspaceSpec(SpecModel):
    """The search area ``A``: a rectangle or a polygon, with polygonal obstacles (Assumption 2.1)."""

    rectangle: tuple[float, float, float, float] | None = None
    corner_radius: float = Field(0.0, ge=0, description="rounds the rectangle's corners (arcs sampled every 5 degrees)")
    bounds: list[Point] | None = None
    obstacles: list[list[Point]] = []

    @model_validator(mode="after")
    def _check(self):
        if (self.rectangle is None) == (self.bounds is None):
            raise ScenarioError("rectangle", "exactly one of rectangle [xmin, ymin, xmax, ymax] or bounds [[x, y], ...]", "both" if self.rectangle else "neither")
        if self.rectangle is not None:
            x0, y0, x1, y1 = self.rectangle
            if not (x1 > x0 and y1 > y0 and all(map(math.isfinite, self.rectangle))):
                raise ScenarioError("rectangle", "finite [xmin, ymin, xmax, ymax] with xmax > xmin and ymax > ymin", list(self.rectangle))
            if 2 * self.corner_radius >= min(x1 - x0, y1 - y0):
                raise ScenarioError("corner_radius", f"a radius below half the rectangle's shorter side ({min(x1 - x0, y1 - y0) / 2:g})", self.corner_radius)
        elif self.corner_radius:
            raise ScenarioError("corner_radius", "0 unless the area is a rectangle", self.corner_radius)
        area = self.workspace().boundary_polygon
        if not area.is_valid or area.area <= 0:
            raise ScenarioError("bounds", "a simple polygon with positive area", self.bounds)
        for k, obs in enumerate(self.obstacles):
            poly = shapely.Polygon(obs)
            if len(obs) < 3 or not poly.is_valid or poly.area <= 0:
                raise ScenarioError(f"obstacles.{k}", "a simple polygon of at least 3 vertices", obs)
            if not area.contains(poly):
                raise ScenarioError(f"obstacles.{k}", "an obstacle inside the area", obs)
            for j in range(k):
                if poly.intersection(shapely.Polygon(self.obstacles[j])).area > 0:
                    raise ScenarioError(f"obstacles.{k}", f"non-overlapping obstacles (Assumption 2.1; overlaps obstacle {j})", obs)
        return self

    def workspace(self) -> Workspace:
        obstacles = tuple(np.asarray(o, dtype=float) for o in self.obstacles)
        if self.rectangle is not None and self.corner_radius == 0:
            return Workspace.rectangle(*self.rectangle, obstacles=obstacles)
        bounds = rounded_rectangle(self.rectangle, self.corner_radius) if self.rectangle is not None else np.asarray(self.bounds, dtype=float)
        return Workspace(ensure_ccw(bounds), tuple(ensure_ccw(o) for o in obstacles))


def rounded_rectangle(rectangle, radius: float, step_degrees: float = 5.0) -> np.ndarray:
    """Counter-clockwise vertices of a rectangle whose corners are arcs of ``radius``."""
    x0, y0, x1, y1 = rectangle
    centres = [(x1 - radius, y0 + radius, -90.0), (x1 - radius, y1 - radius, 0.0), (x0 + radius, y1 - radius, 90.0), (x0 + radius, y0 + radius, 180.0)]
    angles = np.deg2rad(np.arange(0.0, 90.0 + 1e-9, step_degrees))
    pts = [np.column_stack([cx + radius * np.cos(np.deg2rad(a0) + angles), cy + radius * np.sin(np.deg2rad(a0) + angles)]) for cx, cy, a0 in centres]
    return np.concatenate(pts)


class GridSpec(SpecModel):
    """The grid (Section 3): kind and edge length ``a``."""

    kind: GridKind = GridKind.TRIANGULAR
    a: float = 1.0

    @field_validator("a")
    @classmethod
    def _positive(cls, v):
        if not (math.isfinite(v) and v > 0):
            raise ScenarioError("", "a positive edge length a > 0", v)
        return v


class RangesSpec(SpecModel):
    """Robot radius and ranges (Table 1, simulation row, as defaults)."""

    r_rob: float = Field(0.26, ge=0)
    r_safe: float = Field(0.31, ge=0)
    r_so: float = Field(1.31, gt=0)
    r_st: float = Field(1.31, gt=0)
    r_c: float = Field(2.05, ge=0)


class RobotsSpec(SpecModel):
    """Either ``count`` robots at random border vertices (drawn per seed), or explicit ``starts``."""

    count: int | None = Field(None, ge=1)
    starts: list[Point] | None = None

    @model_validator(mode="after")
    def _one(self):
        if (self.count is None) == (self.starts is None):
            raise ScenarioError("count", "exactly one of count or starts", "both" if self.count else "neither")
        if self.starts is not None and len(self.starts) == 0:
            raise ScenarioError("starts", "at least one start", self.starts)
        return self

    @property
    def n(self) -> int:
        return self.count if self.count is not None else len(self.starts)


class FailureSpec(SpecModel):
    """Failure injection: ``robot`` stops moving and answering from step ``step`` on."""

    robot: int = Field(ge=0)
    step: int = Field(ge=0)


class RandomFailuresSpec(SpecModel):
    """Random failure injection for experiments: ``count`` distinct robots, each failing at a
    uniform random step in ``[0, within_steps)`` (drawn per seed from stream ``search-failures``)."""

    count: int = Field(0, ge=0)
    within_steps: int = Field(50, ge=1)


class LevySpec(SpecModel):
    """Parameters of the grid-adapted LFP baseline (:mod:`.levy_flight`)."""

    beta: float = Field(1.5, gt=1.0, le=2.0)
    turn_sigma: float = Field(math.pi / 2, ge=0)
    repulsion: float = Field(1.0, ge=0)
    max_flight: int = Field(20, ge=1)


class Spec(SpecModel):
    """A search scenario (paper 002)."""

    family: Literal["search"] = "search"
    name: str = "search"
    workspace: WorkspaceSpec
    grid: GridSpec = GridSpec()
    ranges: RangesSpec = RangesSpec()
    timing: MotionTiming = MotionTiming()
    algorithm: Algorithm = Algorithm.PROPOSED
    situation: Literal[1, 2] = 1
    targets: list[Point] = []
    robots: RobotsSpec
    failures: list[FailureSpec] = []
    random_failures: RandomFailuresSpec = RandomFailuresSpec()
    max_steps: int = Field(20000, ge=1)
    require_guarantee: bool = False
    levy: LevySpec = LevySpec()

    @model_validator(mode="after")
    def _check(self):
        try:
            grid = self.built_grid()
        except ConfigError:
            raise ScenarioError("grid.a", "an edge length that puts at least one grid vertex inside the area", self.grid.a) from None
        self._check_targets(grid)
        self._check_robots(grid)
        if self.situation == 1 and not self.targets:
            raise ScenarioError("targets", "at least one target in situation 1", self.targets)
        if self.algorithm is Algorithm.LFP and self.situation == 2:
            raise ScenarioError("algorithm", "proposed, rule1 or ru in situation 2 (LFP keeps no map for stop rule (4))", "lfp")
        if self.require_guarantee:
            self._check_guarantee()
        return self

    def built_grid(self) -> Grid:
        """The grid of this scenario (cached per area, kind, ``a`` and ``r_safe``)."""
        ws = self.workspace
        return cached_grid(ws.rectangle, ws.corner_radius, tuple(map(tuple, ws.bounds or [])), tuple(tuple(map(tuple, o)) for o in ws.obstacles),
                           self.grid.kind.value, self.grid.a, self.ranges.r_safe)

    def assumption_report(self) -> AssumptionReport:
        r = self.ranges
        return check_assumptions(self.built_grid().workspace, self.grid.kind, self.grid.a, r.r_rob, r.r_safe, r.r_so, r.r_st, r.r_c)

    def _check_targets(self, grid: Grid) -> None:
        ws = grid.workspace
        for k, t in enumerate(self.targets):
            if not shapely.intersects_xy(ws.boundary_polygon, *t):
                raise ScenarioError(f"targets.{k}", "a target inside the area", list(t))
            if any(shapely.intersects_xy(p, *t) for p in ws.obstacle_polygons):
                raise ScenarioError(f"targets.{k}", "a target outside every obstacle (targets lie in A_d)", list(t))

    def _check_robots(self, grid: Grid) -> None:
        n = self.robots.n
        if self.robots.starts is not None:
            ids, dist = grid.nearest_vertex(np.asarray(self.robots.starts, dtype=float))
            for k, (v, d) in enumerate(zip(ids, dist)):
                if d > 1e-3 * grid.a:
                    raise ScenarioError(f"robots.starts.{k}", f"a grid vertex (nearest is {grid.points[v].round(4).tolist()})", list(self.robots.starts[k]))
                if not grid.accessible[v]:
                    raise ScenarioError(f"robots.starts.{k}", "an accessible vertex (clearance >= r_safe)", list(self.robots.starts[k]))
            if len(set(ids.tolist())) < n:
                raise ScenarioError("robots.starts", "different vertices (Assumption 2.2)", self.robots.starts)
        elif n > len(grid.border_vertices()):
            raise ScenarioError("robots.count", f"at most {len(grid.border_vertices())} robots (border vertices of the grid)", n)
        for k, f in enumerate(self.failures):
            if f.robot >= n:
                raise ScenarioError(f"failures.{k}.robot", f"a robot index below {n}", f.robot)
        if self.random_failures.count >= n and self.random_failures.count:
            raise ScenarioError("random_failures.count", f"fewer failing robots than robots ({n})", self.random_failures.count)

    def _check_guarantee(self) -> None:
        report = self.assumption_report()
        fields = {"safety": "ranges.r_safe", "2.4": "ranges.r_so", "2.5": "ranges.r_c", "3.1.1": "ranges.r_st",
                  "3.1.2": "workspace", "3.1.3": "workspace.obstacles"}
        for c in report.failed():
            raise ScenarioError(fields[c.name], f"Assumption {c.name} ({c.statement}; required {c.required:.4g}) since require_guarantee is true", round(c.value, 6))
        if self.situation == 2 and self.grid.kind is not GridKind.TRIANGULAR:
            raise ScenarioError("grid.kind", "triangular when require_guarantee is true in situation 2 (Section 3)", self.grid.kind.value)


@lru_cache(maxsize=32)
def cached_grid(rectangle, corner_radius, bounds, obstacles, kind: str, a: float, r_safe: float) -> Grid:
    """Build (once per process) the grid of an area."""
    spec = WorkspaceSpec(rectangle=rectangle, corner_radius=corner_radius, bounds=[list(p) for p in bounds] or None,
                         obstacles=[list(o) for o in obstacles])
    return build_grid(spec.workspace(), kind, a, r_safe)


@lru_cache(maxsize=32)
def _sensing_for(grid: Grid, targets: tuple, r_so: float, r_st: float):
    return build_sensing(grid, np.asarray(targets, dtype=float).reshape(-1, 2), r_so, r_st)


def start_vertices(spec: Spec, grid: Grid, seed: int) -> np.ndarray:
    """Start vertex ids: the given starts, or distinct random border vertices (stream ``starts``)."""
    if spec.robots.starts is not None:
        return grid.nearest_vertex(np.asarray(spec.robots.starts, dtype=float))[0]
    border = grid.border_vertices()
    return np.sort(keyed_generator(seed, "search-starts").choice(border, size=spec.robots.count, replace=False))


def failure_steps(spec: Spec, seed: int) -> np.ndarray:
    """Step at which each robot fails (``-1``: never): the listed failures, then the random ones."""
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
    """Resolve a spec into a :class:`SearchProblem` for ``seed`` (start draw included)."""
    grid = spec.built_grid()
    r = spec.ranges
    sensing = _sensing_for(grid, tuple(map(tuple, spec.targets)), r.r_so, r.r_st)
    failures = failure_steps(spec, seed)
    lv = spec.levy
    return SearchProblem(grid, sensing, np.asarray(spec.targets, dtype=float).reshape(-1, 2), start_vertices(spec, grid, seed),
                         spec.situation, r.r_so, r.r_st, r.r_c, spec.timing, failures, spec.max_steps,
                         LevyParameters(lv.beta, lv.turn_sigma, lv.repulsion, lv.max_flight))


def seed_int(seed: RngLike) -> int:
    """An integer seed from any ``RngLike`` (a generator or ``None`` draws one)."""
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return int(seed)
    return int(as_generator(seed).integers(0, 2**63 - 1))


@lru_cache(maxsize=32)
def coverage_probe(grid: Grid, r_st: float) -> CoverageProbe:
    """The cached coverage probe of a grid."""
    return CoverageProbe(grid, r_st)


def simulate(spec: Spec, seed: RngLike = None, progress: bool = False) -> Trace:
    """Run one search and return its :class:`Trace`.

    Arrays: ``positions (n_steps, n_robots, 2)`` (true vertex coordinates), ``vertex
    (n_steps, n_robots, 1)`` ids, ``time (n_steps, n_robots, 1)`` seconds since the start.
    Results: ``search_time``, ``found_targets``, ``visited_share``, ``detected_share``,
    ``collisions``, ``completed`` … Events: ``target_found``, ``failure``,
    ``failure_detected``, ``collision``, ``obstacle_collision``, ``stop``.
    """
    seed = seed_int(seed)
    problem = build_problem(spec, seed)
    outcome = run_search(problem, spec.algorithm, seed, record=True)
    grid = problem.grid
    results = dict(outcome.results)
    results["detected_share"] = coverage_probe(grid, spec.ranges.r_st).detected_share(outcome.visited)
    verts = outcome.vertices
    n_steps = len(verts)
    arrays = {
        "positions": grid.points[verts],
        "vertex": verts[:, :, None].astype(np.int64),
        "time": np.repeat(outcome.times[:, None, None], problem.n_robots, axis=1),
    }
    metadata = {
        "family": "search", "name": spec.name, "seed": seed, "algorithm": spec.algorithm.value,
        "algorithm_label": LABELS[spec.algorithm], "situation": spec.situation, "grid": grid.kind.value, "a": grid.a,
        "ranges": spec.ranges.model_dump(), "radius": spec.ranges.r_rob, "targets": problem.targets.tolist(),
        "starts": problem.starts.tolist(), "grid_points": grid.points.tolist(), "accessible": grid.accessible.tolist(),
        "visited": outcome.visited.tolist(), "n_steps": n_steps, "assumptions": spec.assumption_report().as_dict(),
    }
    return Trace("search", arrays, outcome.events, metadata, results, grid.workspace)
