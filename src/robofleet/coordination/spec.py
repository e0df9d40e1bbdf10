"""Scenario files of the ``coordination`` family: :class:`Spec`, the frozen, validated model.

Example::

    family: coordination
    workspace: {preset: x_corridor}
    disturbance: {base_probability: 0.05, region_probability: 0.85}
    robots: {count: 20, radius: 15, speed: 50, placement: flows, instance_seed: 3}
    policy: {method: tfa, deadlock_check: true, estimate: known}
    simulation: {dt: 0.1, max_steps: 30000}

``workspace``
    The shared vocabulary of :mod:`robofleet.core.spec_blocks` (``bounds``, ``obstacles``,
    ``regions``) plus ``preset: x_corridor``, the map of the label-flipping deadlock paper (2021)'s Fig. 1 (the default),
    or ``preset: warehouse``, a grid of shelves (:func:`~.maps.warehouse_workspace`).
    Giving ``bounds`` means a map of one's own (``preset`` then defaults to null).
    Obstacles and regions given with the preset are added to the preset map. Every
    region carries the disturbance ``probability`` of the robots inside it.
``robots``
    From the flows of the map (``placement: flows``: ``count`` robots in random boxes), at
    random pick stations of the warehouse (``placement: stations``) or ``explicit``
    ``starts``/``goals``. The random instance comes from ``instance_seed``, or,
    when it is null (the default), from the run's seed, so that a sweep over seeds gives
    one instance per seed, shared by every policy variant (a paired comparison).
``policy``
    ``method``: ``rmtrack``, ``tff``, ``tfa`` (the paper's, with ``deadlock_check`` as an
    option), ``btpg`` (:mod:`.btpg`; ``btpg_budget`` bounds its offline classification) or
    ``optimal`` (:mod:`.optimal`; its ``optimal:`` block sets the horizon, the number of
    obstacles decided at once, the node budget and the decision period).
``trajectories``
    Optional plan file (``plan.csv`` with header ``robot,step,x,y``, or ``.npz``), relative
    to the scenario file; without it the prioritized planner plans the trajectories.
    Validation reads the file (when the scenario's file is known, see :meth:`Spec._plan_file`)
    and reports a bad row or column on one line.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal, Optional, Union

import numpy as np
from pydantic import Field, ValidationInfo, model_validator

from ..core.budget import RunSize
from ..core.config import SpecModel, as_array
from ..core.errors import ScenarioError
from ..core.rng import MAX_SEED
from ..core.spec_blocks import Point, RegionSpec, WorkspaceSpec
from ..core.workspace import Workspace
from .endpoints import check_endpoints
from .maps import warehouse_stations, warehouse_workspace, x_corridor_workspace
from .options import DEFAULT_VISIT_BUDGET, Estimate, Method, OptimalSettings, Resolution
from .trajectories import Trajectories, first_plan_collision, load_trajectories

ROADMAP_EDGE_BYTES = 200
"""Memory of one candidate roadmap edge while the roadmap is built (its node pair and segment)."""


class DisturbanceRegionSpec(RegionSpec):
    """A named polygon inside which a robot's step fails with ``probability`` (the label-flipping deadlock paper (2021)'s red region)."""

    probability: float = Field(ge=0.0, lt=1.0)


class CoordinationWorkspaceSpec(WorkspaceSpec):
    """The shared ``workspace:`` block plus ``preset: x_corridor`` (Fig. 1's map, the default).

    With the preset, ``bounds`` stay null and ``obstacles`` and ``regions`` are added to
    the preset map; giving ``bounds`` without ``preset`` means a map of one's own.
    """

    preset: Optional[Literal["x_corridor", "warehouse"]] = "x_corridor"
    bounds: Optional[Union[tuple[float, float, float, float], list[Point]]] = None
    regions: list[DisturbanceRegionSpec] = Field(default_factory=list)

    @model_validator(mode="before")
    @classmethod
    def _bounds_mean_own_map(cls, data):
        """``bounds`` (or its alias ``rectangle``) without ``preset`` selects no preset."""
        given = isinstance(data, dict) and (data.get("bounds") is not None or data.get("rectangle") is not None)
        if given and "preset" not in data:
            data = {**data, "preset": None}
        return data

    @model_validator(mode="after")
    def _geometry(self):
        """The preset map alone, or bounds of one's own (checked as in every family)."""
        if self.preset is not None:
            if self.bounds is not None:
                raise ScenarioError("preset", "null when bounds are given (a preset map has its own bounds)", self.preset)
            if self.corner_radius:
                raise ScenarioError("corner_radius", "0 with a preset map", self.corner_radius)
            return self
        if self.bounds is None:
            raise ScenarioError("bounds", "the map's bounds when preset is null", None)
        return super()._geometry()

    def build(self, region_probability: float = 0.85) -> Workspace:
        """The workspace; the preset's own disturbance region has ``region_probability``."""
        if self.preset is None:
            return super().build()
        base = (warehouse_workspace if self.preset == "warehouse" else x_corridor_workspace)(region_probability)
        return Workspace(base.bounds, base.obstacles + tuple(self.obstacle_polygons()),
                         base.regions + tuple(r.build() for r in self.regions))


class DisturbanceSpec(SpecModel):
    """Per-step disturbance probability: ``base_probability`` outside every region,
    ``region_probability`` in the preset map's region."""

    base_probability: float = Field(0.05, ge=0.0, lt=1.0)
    region_probability: float = Field(0.85, ge=0.0, lt=1.0)


class RobotsSpec(SpecModel):
    """Team size, disc radius, top speed, and where the robots start and go."""

    count: Optional[int] = Field(None, ge=1)
    radius: float = Field(15.0, gt=0.0)
    speed: float = Field(50.0, gt=0.0)
    placement: Literal["flows", "explicit", "stations"] = "flows"
    instance_seed: Optional[int] = Field(None, ge=0, le=MAX_SEED)
    starts: Optional[list[list[float]]] = None
    goals: Optional[list[list[float]]] = None

    @model_validator(mode="after")
    def _consistent(self):
        if self.placement == "explicit":
            if self.starts is None or self.goals is None:
                raise ScenarioError("starts", "starts and goals with placement: explicit", None)
            s, g = as_array(self.starts, (2,), "starts"), as_array(self.goals, (2,), "goals")
            if s.ndim != 2 or s.shape != g.shape:
                raise ScenarioError("goals", f"{len(s)} points like starts", f"shape {g.shape}")
            if self.count is not None and self.count != len(s):
                raise ScenarioError("count", f"{len(s)} (the number of starts)", self.count)
        elif self.count is None:
            raise ScenarioError("count", f"a robot count with placement: {self.placement}", None)
        elif self.placement == "stations" and 2 * self.count > len(warehouse_stations()):
            raise ScenarioError("count", f"at most {len(warehouse_stations()) // 2} robots with placement: stations (two stations each)",
                                self.count)
        return self

    @property
    def n(self) -> int:
        """Number of robots."""
        return len(self.starts) if self.placement == "explicit" else int(self.count)


class OptimalSpec(SpecModel):
    """``policy.optimal``: the search of ``method: optimal`` (:class:`~.optimal.OptimalSettings`)."""

    horizon: int = Field(OptimalSettings.horizon, ge=1)
    max_open: int = Field(OptimalSettings.max_open, ge=1)
    node_budget: int = Field(OptimalSettings.node_budget, ge=0)
    period: int = Field(OptimalSettings.period, ge=1)

    def settings(self) -> OptimalSettings:
        return OptimalSettings(horizon=self.horizon, max_open=self.max_open, node_budget=self.node_budget, period=self.period)


class PolicySpec(SpecModel):
    """The execution policy: RMTRACK alone, with a flip test or BTPG's first-come rule, or
    the optimal orders; the deadlock check of the flip tests, and where the expected
    travel times' probabilities come from."""

    method: Method = Method.TFA
    deadlock_check: bool = True
    estimate: Estimate = Estimate.KNOWN
    resolution: Resolution = Resolution.EXACT
    learned_cell: float = Field(150.0, gt=0.0)
    btpg_budget: int = Field(DEFAULT_VISIT_BUDGET, ge=0)
    optimal: OptimalSpec = OptimalSpec()


class SimulationSpec(SpecModel):
    """Step length Δ in seconds and the step budget."""

    dt: float = Field(0.1, gt=0.0)
    max_steps: int = Field(30000, ge=1)


class PlannerSpec(SpecModel):
    """Roadmap and space-time search of the prioritized planner (RPP)."""

    grid_spacing: float = Field(75.0, gt=0.0)
    connection_radius: float = Field(120.0, gt=0.0)
    wait_steps: int = Field(5, ge=1)
    max_steps: int = Field(20000, ge=1)


class Spec(SpecModel):
    """A coordination scenario (see the module docstring)."""

    family: Literal["coordination"] = "coordination"
    name: str = ""
    workspace: CoordinationWorkspaceSpec = CoordinationWorkspaceSpec()
    disturbance: DisturbanceSpec = DisturbanceSpec()
    robots: RobotsSpec
    trajectories: Optional[str] = None
    policy: PolicySpec = PolicySpec()
    simulation: SimulationSpec = SimulationSpec()
    planner: PlannerSpec = PlannerSpec()

    @model_validator(mode="after")
    def _stations_need_the_warehouse(self):
        """``placement: stations`` draws from the warehouse's pick stations."""
        if self.robots.placement == "stations" and self.workspace.preset != "warehouse":
            raise ScenarioError("robots.placement", "stations only with workspace preset warehouse (its pick stations)",
                                f"stations with preset {self.workspace.preset}")
        return self

    @model_validator(mode="after")
    def _endpoints_free(self):
        """Explicit starts and goals to be planned lie in the free space, ``2r`` apart."""
        if self.robots.placement == "explicit" and self.trajectories is None:
            check_endpoints(self.build_workspace(), np.asarray(self.robots.starts, float),
                            np.asarray(self.robots.goals, float), self.robots.radius)
        return self

    @model_validator(mode="after")
    def _plan_file(self, info: ValidationInfo):
        """Read the plan file now, so a bad file fails validation (one line naming the file,
        row and column).

        A relative path is resolved beside the scenario file, which the validation
        context names (``context={"source": path}``; ``None`` for a mapping, relative to
        the working directory). Without that context a relative path is read when the
        scenario runs.
        """
        if self.trajectories is None:
            return self
        path = plan_path(self.trajectories, info.context)
        if path is not None:
            try:
                self.load_plan(path)
            except ScenarioError as exc:
                inner = f"{exc.source}: {exc.field}" if exc.field else str(exc.source)
                raise ScenarioError(f"trajectories: {inner}", exc.expected, exc.received) from None
        return self

    # -- memory budget (input validation, robofleet.core.budget) --------------------------
    def run_size(self) -> RunSize:
        """What a run holds: per robot and step a position, the progress and two flags;
        a planned instance adds the roadmap (grid nodes ``grid_spacing`` apart, each joined
        to the nodes within ``connection_radius``) and the plan of up to
        ``planner.max_steps + 1`` points per robot (held, then recorded)."""
        n = self.robots.n
        robots_field = "robots.starts" if self.robots.placement == "explicit" else "robots.count"
        if self.trajectories is not None:  # a plan file: its points (a CSV row of ≥ 8 bytes gives 16), held and recorded
            path = plan_path(self.trajectories, {"source": self.source})
            size = path.stat().st_size if path is not None and path.is_file() else 0
            return RunSize(self.simulation.max_steps, n, 16 + 8 + 2, "simulation.max_steps", robots_field,
                           2 * 2 * size if path is not None and path.suffix.lower() == ".csv" else 0, "plan", "trajectories")
        xmin, ymin, xmax, ymax = self.build_workspace().extent
        spacing, reach = self.planner.grid_spacing, self.planner.connection_radius
        nodes = math.ceil((xmax - xmin) / spacing) * math.ceil((ymax - ymin) / spacing) + 2 * n
        edges = nodes * math.pi * (reach / spacing + 1) ** 2
        plan = 2 * 16 * n * (self.planner.max_steps + 1)
        return RunSize(self.simulation.max_steps, n, 16 + 8 + 2, "simulation.max_steps", robots_field,
                       int(16 * nodes + ROADMAP_EDGE_BYTES * edges + plan), "roadmap and plan",
                       f"planner.grid_spacing, planner.connection_radius, workspace, planner.max_steps, {robots_field}")

    def build_workspace(self) -> Workspace:
        """The scenario's workspace with its disturbance regions (``probability`` attributes)."""
        return self.workspace.build(self.disturbance.region_probability)

    def plan_file(self) -> Path:
        """The plan file, resolved beside the scenario file (or the working directory)."""
        return plan_path(self.trajectories, {"source": self.source})

    def load_plan(self, path: Path | None = None, workspace: Workspace | None = None) -> Trajectories:
        """Read and check the plan file: one trajectory per robot, each point in the free space.

        Raises
        ------
        ScenarioError
            Naming the plan file: unreadable, bad row or column, wrong robot count, a
            point closer than ``r`` to a wall or an obstacle, two robots closer than ``2r``
            (the plan must be collision-free, RMTRACK's premise).
        """
        path = path or self.plan_file()
        traj = load_trajectories(path, self.robots.radius, self.simulation.dt)
        if self.robots.placement == "explicit" and traj.n_robots != self.robots.n:
            raise ScenarioError("trajectories", f"{self.robots.n} trajectories (one per robot)", traj.n_robots, source=str(path))
        check_inside(traj, workspace or self.build_workspace(), str(path))
        check_collision_free(traj, str(path))
        return traj


def plan_path(trajectories: str, context: dict | None) -> Path | None:
    """``trajectories`` as a path: absolute, or beside ``context["source"]`` (the working
    directory when that is ``None``); ``None`` when relative and ``context`` names no source."""
    path = Path(trajectories)
    if path.is_absolute():
        return path
    if not isinstance(context, dict) or "source" not in context:
        return None
    source = context["source"]
    return Path(source).parent / path if source else path


def check_collision_free(traj: Trajectories, source: str) -> None:
    """No two robots of a loaded plan come closer than ``2r`` when it runs undisturbed."""
    hit = first_plan_collision(traj)
    if hit is not None:
        i, j, step, distance = hit
        raise ScenarioError("", f"a collision-free plan (robots at least 2r = {2 * traj.radius:g} apart at every step)",
                            f"robots {i} and {j} {distance:.4g} apart at plan step {step}", source=source)


def check_inside(traj: Trajectories, workspace: Workspace, source: str) -> None:
    """Every point of a loaded plan keeps clearance ``≥ r`` from walls and obstacles."""
    clearance = workspace.clearance(traj.positions)
    bad = np.argwhere(clearance < traj.radius * (1 - 1e-9))
    if len(bad):
        i, k = (int(v) for v in bad[0])
        raise ScenarioError(f"trajectories[{i}][{k}]", f"a point inside the free space with clearance >= radius {traj.radius}",
                            traj.positions[i, k].round(3).tolist(), source=source)
