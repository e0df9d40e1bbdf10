"""Scenario files of the ``search`` family: :class:`Spec`, the validated scenario model.

A file looks like::

    family: search
    workspace: {bounds: [0, 0, 12, 10], obstacles: [[[3, 3], [5, 3], [5, 5], [3, 5]]]}
    grid: {kind: triangular, a: 1.0}
    ranges: {r_rob: 0.26, r_safe: 0.31, r_so: 1.31, r_st: 1.31, r_c: 2.05}   # Table 1
    algorithm: proposed          # proposed | rule1 | ru | lfp
    situation: 1                 # 1: number of targets known, 2: search everything
    targets: [[2, 2], [6, 8]]
    robots: {count: 3}           # random border vertices per seed, or starts: [[x, y], ...]
    failures: [{robot: 1, step: 10}]
    require_guarantee: false     # true: every assumption must hold (else an error)

``workspace:`` is the shared vocabulary of :mod:`robofleet.core.spec_blocks` (``bounds``
or its alias ``rectangle``, ``corner_radius``, ``obstacles`` as boxes or vertex lists),
tightened by Assumption 2.1 (:class:`SearchWorkspaceSpec`). Obstacles are unknown to the
robots: the simulation gives them only what they sense.
"""

from __future__ import annotations

import math
from enum import Enum
from functools import lru_cache
from typing import Literal

import numpy as np
import shapely
from pydantic import Field, field_validator, model_validator

from ..core.budget import RunSize
from ..core.config import SpecModel
from ..core.errors import ConfigError, ScenarioError
from ..core.spec_blocks import WorkspaceSpec
from ..core.workspace import Workspace
from .assumptions import AssumptionReport, check_assumptions
from .grids import VERTEX_BYTES, Grid, GridKind, build_grid, vertex_bound
from .map_words import BLOCK_WORDS, LAYERS, WORD
from .timing import MotionTiming

Point = tuple[float, float]


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
"""The algorithms' names in Fig. 7's legend."""

REQUIRED_FIELD = {"safety": "ranges.r_safe", "2.4": "ranges.r_so", "2.5": "ranges.r_c", "3.1.1": "ranges.r_st",
                  "3.1.2": "workspace", "3.1.3": "workspace.obstacles", "connected": "workspace.obstacles"}
"""The scenario field an error names when an assumption fails under ``require_guarantee``."""


SENSING_BYTES = 40
"""Bytes per vertex of the sensing tables besides the target table (:mod:`.sensing`: two
``(V, k ≤ 6)`` masks and the ``(V, 2)`` wall push); the target table adds one per target."""
MAP_BYTES = LAYERS / 8 + 4 / (WORD * BLOCK_WORDS)
"""Bytes per vertex of one robot's map (:mod:`robofleet.search.knowledge`: four bit layers, four block flags)."""


class SearchWorkspaceSpec(WorkspaceSpec):
    """The search area ``A`` and its obstacles ``O_1 … O_l`` (Assumption 2.1).

    The shared workspace block, tightened: every obstacle lies inside the area and no two
    obstacles overlap ("obstacles O_i are non-overlapping, closed bounded and linearly
    connected sets"); the search has no named regions.
    """

    @model_validator(mode="after")
    def _assumption_2_1(self):
        if self.regions:
            raise ScenarioError("regions", "no regions (the grid search has none)", [r.name for r in self.regions])
        problem = obstacle_problem(self.model_dump_json())
        if problem is not None:
            raise ScenarioError(*problem)
        return self


@lru_cache(maxsize=32)
def obstacle_problem(workspace_json: str) -> tuple[str, str, list] | None:
    """The first obstacle outside the area or overlapping an earlier one (Assumption 2.1),
    as ``ScenarioError`` arguments, or ``None``; once per process per workspace block."""
    workspace = WorkspaceSpec.model_validate_json(workspace_json)
    area = shapely.Polygon(workspace.bounds_vertices())
    polygons = [shapely.Polygon(p) for p in workspace.obstacle_polygons()]
    for k, poly in enumerate(polygons):
        if not area.contains(poly):
            return f"obstacles.{k}", "an obstacle inside the area", poly.exterior.coords[:-1]
        for j in range(k):
            if poly.intersection(polygons[j]).area > 0:
                return (f"obstacles.{k}", f"non-overlapping obstacles (Assumption 2.1; overlaps obstacle {j})",
                        poly.exterior.coords[:-1])
    return None


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
    """A search scenario (Yang 2017)."""

    family: Literal["search"] = "search"
    name: str = ""
    workspace: SearchWorkspaceSpec
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

    # -- memory budget (input validation, robofleet.core.budget) --------------------------
    def run_size(self) -> RunSize:
        """What a run holds: per robot and step a position, a vertex and a clock; the grid
        (at most :func:`.grids.vertex_bound` vertices of the area's bounding box), its sensing
        tables (linear in V) and every robot's map (four bits per vertex and its targets)."""
        vertices = area_vertex_bound(self.workspace.model_dump_json(), self.grid.a)
        n, targets = self.robots.n, len(self.targets)
        extra = (VERTEX_BYTES + SENSING_BYTES + targets) * vertices + n * (MAP_BYTES * vertices + targets)
        robots_field = "robots.count" if self.robots.count is not None else "robots.starts"
        target_share = targets * (vertices + n) / max(extra, 1)
        extra_fields = f"grid.a, workspace, {robots_field}" + (", targets" if target_share >= 0.1 else "")
        return RunSize(self.max_steps, n, 32, "max_steps", robots_field, int(min(extra, 2**62)), "grid, sensing tables and maps", extra_fields)

    def built_grid(self) -> Grid:
        """The grid of this scenario (built once per process per area, kind, ``a`` and ``r_safe``)."""
        return cached_grid(self.workspace.model_dump_json(), self.grid.kind.value, self.grid.a, self.ranges.r_safe)

    def assumption_report(self) -> AssumptionReport:
        """Assumptions 2.4, 2.5, 3.1.1–3.1.3 and the grid's connectivity evaluated for this
        scenario (:func:`.assumptions.check_assumptions`)."""
        r = self.ranges
        return cached_report(self.workspace.model_dump_json(), self.grid.kind.value, self.grid.a, self.ranges.r_safe,
                             r.r_rob, r.r_so, r.r_st, r.r_c)

    def _check_targets(self, grid: Grid) -> None:
        problem = target_problem(grid, tuple(map(tuple, self.targets)))
        if problem is not None:
            k, expected = problem
            raise ScenarioError(f"targets.{k}", expected, list(self.targets[k]))

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
        elif n > len(border_vertices(grid)):
            raise ScenarioError("robots.count", f"at most {len(border_vertices(grid))} robots (border vertices of the grid)", n)
        for k, f in enumerate(self.failures):
            if f.robot >= n:
                raise ScenarioError(f"failures.{k}.robot", f"a robot index below {n}", f.robot)
        if self.random_failures.count >= n and self.random_failures.count:
            raise ScenarioError("random_failures.count", f"fewer failing robots than robots ({n})", self.random_failures.count)

    def _check_guarantee(self) -> None:
        report = self.assumption_report()
        for c in report.failed():
            numbered = c.name[0].isdigit()
            what = f"Assumption {c.name} ({c.statement}; required {c.required:.4g})" if numbered else f"{c.statement} (required {c.required:.4g})"
            raise ScenarioError(REQUIRED_FIELD[c.name], f"{what} since require_guarantee is true", c.evidence or round(c.value, 6))
        if self.situation == 2 and self.grid.kind is not GridKind.TRIANGULAR:
            raise ScenarioError("grid.kind", "triangular when require_guarantee is true in situation 2 (Section 3)", self.grid.kind.value)


@lru_cache(maxsize=64)
def target_problem(grid: Grid, targets: tuple) -> tuple[int, str] | None:
    """The first target outside the area or inside an obstacle (targets lie in ``A_d``), as
    ``(index, expectation)``, or ``None``; once per process per grid and target list."""
    ws = grid.workspace
    obstacles = ws.obstacle_polygons
    for k, t in enumerate(targets):
        if not shapely.intersects_xy(ws.boundary_polygon, *t):
            return k, "a target inside the area"
        if any(shapely.intersects_xy(p, *t) for p in obstacles):
            return k, "a target outside every obstacle (targets lie in A_d)"
    return None


@lru_cache(maxsize=64)
def area_vertex_bound(workspace_json: str, a: float) -> float:
    """:func:`.grids.vertex_bound` of the bounding box of a workspace block's area."""
    bounds = WorkspaceSpec.model_validate_json(workspace_json).bounds_vertices()
    lower, upper = bounds.min(axis=0), bounds.max(axis=0)
    return vertex_bound(*(upper - lower), a)


@lru_cache(maxsize=32)
def cached_workspace(workspace_json: str) -> Workspace:
    """The :class:`Workspace` of a validated workspace block (given as its JSON dump)."""
    return SearchWorkspaceSpec.model_validate_json(workspace_json).build()


@lru_cache(maxsize=32)
def cached_grid(workspace_json: str, kind: str, a: float, r_safe: float) -> Grid:
    """Build (once per process) the grid of an area (Section 3, :func:`.grids.build_grid`)."""
    return build_grid(cached_workspace(workspace_json), kind, a, r_safe)


@lru_cache(maxsize=64)
def cached_report(workspace_json: str, kind: str, a: float, r_safe: float, r_rob: float, r_so: float, r_st: float,
                  r_c: float) -> AssumptionReport:
    """:func:`.assumptions.check_assumptions` on the grid's workspace, once per process per instance."""
    grid = cached_grid(workspace_json, kind, a, r_safe)
    return check_assumptions(grid.workspace, kind, a, r_rob, r_safe, r_so, r_st, r_c, grid=grid)


@lru_cache(maxsize=32)
def border_vertices(grid: Grid) -> np.ndarray:
    """:meth:`.grids.Grid.border_vertices` (Assumption 2.2's start vertices), once per grid."""
    border = grid.border_vertices()
    border.flags.writeable = False
    return border
