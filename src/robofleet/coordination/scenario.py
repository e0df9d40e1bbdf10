"""Scenario files of the ``coordination`` family (registry contract: ``Spec`` + ``simulate``).

Example::

    family: coordination
    workspace: {preset: x_corridor}
    disturbance: {base_probability: 0.05, region_probability: 0.85}
    robots: {count: 20, radius: 15, speed: 50, placement: flows, instance_seed: 3}
    policy: {method: tfa, deadlock_check: true, estimate: known}
    simulation: {dt: 0.1, max_steps: 30000}

Robots come from the flows of the map (``placement: flows``, random boxes drawn with
``instance_seed``) or from explicit ``starts``/``goals``; their trajectories from the
prioritized planner or from a user's file (``trajectories: plan.csv`` / ``.npz``, relative
to the scenario file). ``simulate`` runs one variant; :mod:`.reproduce` runs all six.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, Optional

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..core.errors import ScenarioError
from ..core.geometry import ensure_ccw
from ..core.rng import RngLike, keyed_generator
from ..core.trace import Trace
from ..core.workspace import Region, Workspace
from ..core.config import SpecModel, as_array
from .coordination_space import CoordinationSpace, build_coordination_space
from .label_flipping import KnownProbabilities, LearnedProbabilities
from .maps import probability_map, sample_flow_instance, x_corridor_workspace
from .planner import PlannerSettings, check_endpoints, plan_prioritized
from .segment_graph import Resolution
from .simulation import Estimate, Execution, PlanExecutor, Method, Variant
from .trajectories import Trajectories, load_trajectories


class RegionSpec(SpecModel):
    name: str
    vertices: list[list[float]]
    probability: float = Field(ge=0.0, lt=1.0)

    @field_validator("vertices")
    @classmethod
    def _polygon(cls, v):
        as_array(v, (2,), "vertices")
        if len(v) < 3:
            raise ScenarioError("", "at least 3 vertices", v)
        return v


class WorkspaceSpec(SpecModel):
    """``preset: x_corridor`` (the map of Fig. 1) or an explicit polygon with obstacles."""

    preset: Optional[Literal["x_corridor"]] = "x_corridor"
    bounds: Optional[list[list[float]]] = None
    obstacles: list[list[list[float]]] = []
    regions: list[RegionSpec] = []

    @model_validator(mode="after")
    def _one_source(self):
        if self.preset is None and self.bounds is None:
            raise ScenarioError("bounds", "a polygon when preset is null", None)
        if self.bounds is not None:
            as_array(self.bounds, (2,), "bounds")
        return self


class DisturbanceSpec(SpecModel):
    base_probability: float = Field(0.05, ge=0.0, lt=1.0)
    region_probability: float = Field(0.85, ge=0.0, lt=1.0)


class RobotsSpec(SpecModel):
    count: Optional[int] = Field(None, ge=1)
    radius: float = Field(15.0, gt=0.0)
    speed: float = Field(50.0, gt=0.0)
    placement: Literal["flows", "explicit"] = "flows"
    instance_seed: int = Field(0, ge=0)
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
            raise ScenarioError("count", "a robot count with placement: flows", None)
        return self

    @property
    def n(self) -> int:
        return len(self.starts) if self.placement == "explicit" else int(self.count)


class PolicySpec(SpecModel):
    method: Method = Method.TFA
    deadlock_check: bool = True
    estimate: Estimate = Estimate.KNOWN
    resolution: Resolution = Resolution.EXACT
    learned_cell: float = Field(150.0, gt=0.0)


class SimulationSpec(SpecModel):
    dt: float = Field(0.1, gt=0.0)
    max_steps: int = Field(30000, ge=1)


class PlannerSpec(SpecModel):
    grid_spacing: float = Field(75.0, gt=0.0)
    connection_radius: float = Field(120.0, gt=0.0)
    wait_steps: int = Field(5, ge=1)
    max_steps: int = Field(20000, ge=1)


class Spec(SpecModel):
    family: Literal["coordination"] = "coordination"
    workspace: WorkspaceSpec = WorkspaceSpec()
    disturbance: DisturbanceSpec = DisturbanceSpec()
    robots: RobotsSpec
    trajectories: Optional[str] = None
    policy: PolicySpec = PolicySpec()
    simulation: SimulationSpec = SimulationSpec()
    planner: PlannerSpec = PlannerSpec()

    @model_validator(mode="after")
    def _geometry(self):
        if self.robots.placement == "explicit" and self.trajectories is None:
            ws = build_workspace(self)
            try:
                check_endpoints(ws, np.asarray(self.robots.starts, float), np.asarray(self.robots.goals, float), self.robots.radius)
            except ScenarioError as exc:
                raise ScenarioError(exc.field, exc.expected, exc.received) from None
        return self


def build_workspace(spec: Spec) -> Workspace:
    """The scenario's workspace with its disturbance regions (``probability`` attributes)."""
    w = spec.workspace
    extra = tuple(Region(r.name, np.asarray(r.vertices, float), {"probability": r.probability}) for r in w.regions)
    if w.preset == "x_corridor" and w.bounds is None:
        base = x_corridor_workspace(spec.disturbance.region_probability)
        return Workspace(base.bounds, base.obstacles, base.regions + extra)
    return Workspace(ensure_ccw(np.asarray(w.bounds, float)), tuple(ensure_ccw(np.asarray(o, float)) for o in w.obstacles), extra)


def robot_endpoints(spec: Spec, workspace: Workspace) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals: explicit, or drawn in the flows' boxes from ``instance_seed``."""
    r = spec.robots
    if r.placement == "explicit":
        return np.asarray(r.starts, float), np.asarray(r.goals, float)
    return sample_flow_instance(workspace, r.n, r.radius, keyed_generator(r.instance_seed, "instance"))


def planner_settings(spec: Spec) -> PlannerSettings:
    p = spec.planner
    return PlannerSettings(radius=spec.robots.radius, speed=spec.robots.speed, dt=spec.simulation.dt,
                           grid_spacing=p.grid_spacing, connection_radius=p.connection_radius,
                           wait_steps=p.wait_steps, max_steps=p.max_steps)


def build_plan(spec: Spec, workspace: Workspace | None = None) -> Trajectories:
    """The scenario's trajectories: loaded from its file, or planned with RPP."""
    workspace = workspace or build_workspace(spec)
    if spec.trajectories is not None:
        path = Path(spec.trajectories)
        if not path.is_absolute() and spec.source:
            path = Path(spec.source).parent / path
        traj = load_trajectories(path, spec.robots.radius, spec.simulation.dt)
        if spec.robots.placement == "explicit" and traj.n_robots != spec.robots.n:
            raise ScenarioError("trajectories", f"{spec.robots.n} trajectories (one per robot)", traj.n_robots, source=spec.source)
        _check_inside(traj, workspace, str(path))
        return traj
    starts, goals = robot_endpoints(spec, workspace)
    return plan_prioritized(workspace, starts, goals, planner_settings(spec))


def _check_inside(traj: Trajectories, workspace: Workspace, source: str) -> None:
    """Every point of a loaded plan keeps clearance ``≥ r`` from walls and obstacles."""
    clearance = workspace.clearance(traj.positions)
    bad = np.argwhere(clearance < traj.radius * (1 - 1e-9))
    if len(bad):
        i, k = (int(v) for v in bad[0])
        raise ScenarioError(f"trajectories[{i}][{k}]", f"a point inside the free space with clearance >= radius {traj.radius}",
                            traj.positions[i, k].round(3).tolist(), source=source)


def probabilities_along(traj: Trajectories, workspace: Workspace, base_probability: float) -> np.ndarray:
    """True disturbance probability at every plan step ``(n, K_max + 1)``."""
    return probability_map(workspace, traj.positions, base_probability)


def make_executor(traj: Trajectories, space: CoordinationSpace, workspace: Workspace, variant: Variant,
                  base_probability: float, estimate: Estimate = Estimate.KNOWN, resolution: Resolution = Resolution.EXACT,
                  learned_cell: float = 150.0, layout=None) -> PlanExecutor:
    """An :class:`PlanExecutor` wired with the map's probabilities (known or learned online)."""
    prob = probabilities_along(traj, workspace, base_probability)
    cells = None
    if estimate is Estimate.LEARNED:
        xmin, ymin, xmax, ymax = workspace.extent
        nx = int(np.ceil((xmax - xmin) / learned_cell)) + 1
        ix = np.clip(((traj.positions[..., 0] - xmin) // learned_cell).astype(int), 0, nx - 1)
        iy = np.clip(((traj.positions[..., 1] - ymin) // learned_cell).astype(int), 0, None)
        cells = iy * nx + ix
        times = LearnedProbabilities(cells, int(cells.max()) + 1, traj.dt, prior=base_probability)
    else:
        times = KnownProbabilities(prob, traj.dt)
    return PlanExecutor(traj, space, variant, times, prob, layout=layout, resolution=resolution, observe_cells=cells)


def simulate(spec: Spec, seed: RngLike = None, progress: bool = False) -> Trace:
    """Plan (or load) the trajectories and execute them with the scenario's policy.

    ``seed`` drives the disturbances only (one stream per robot and step); the instance
    comes from ``robots.instance_seed``, so every policy run with the same seed meets the
    same plan and the same disturbances.
    """
    seed_int = _seed_int(seed)
    workspace = build_workspace(spec)
    traj = build_plan(spec, workspace)
    space = build_coordination_space(traj)
    variant = Variant(spec.policy.method, spec.policy.deadlock_check)
    ex = make_executor(traj, space, workspace, variant, spec.disturbance.base_probability, spec.policy.estimate,
                       spec.policy.resolution, spec.policy.learned_cell)
    run = ex.run(seed_int, spec.simulation.max_steps)
    return execution_trace(traj, run, workspace, variant, seed_int, spec.disturbance.base_probability)


def _seed_int(seed: RngLike) -> int:
    if seed is None:
        return 0
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return int(seed)
    return int(np.random.default_rng(seed).integers(2**62))


def travel_metrics(traj: Trajectories, run: Execution) -> dict:
    """Travel times in seconds (``nan`` when a robot never arrived)."""
    arrived = run.arrival_steps >= 0
    times = np.where(arrived, run.arrival_steps * traj.dt, np.nan)
    ok = bool(arrived.all())
    return {
        "mean_travel_time": float(np.mean(times)) if ok else float("nan"),
        "total_travel_time": float(np.sum(times)) if ok else float("nan"),
        "makespan": float(np.max(times)) if ok else float("nan"),
        "planned_mean_travel_time": float(np.mean(traj.lengths) * traj.dt),
    }


def execution_trace(traj: Trajectories, run: Execution, workspace: Workspace, variant: Variant, seed: int,
                    base_probability: float) -> Trace:
    """The run as a :class:`Trace` (positions, progress, waiting flags, plan; events; results)."""
    positions = traj.positions[np.arange(traj.n_robots)[None, :], np.minimum(run.progress, traj.lengths)]
    results = {
        "deadlock": run.deadlock, "finished": run.finished, "flips": run.flips, "refused_flips": run.refused_flips,
        "flip_tests": run.flip_tests, "decision_seconds": run.decision_seconds, "collision_events": run.collisions,
        **travel_metrics(traj, run),
    }
    metadata = {
        "method": variant.name, "dt": traj.dt, "radius": traj.radius, "goals": traj.goals.tolist(),
        "goal_tolerance": 0.0, "seed": seed, "base_probability": base_probability, "n_robots": traj.n_robots,
    }
    arrays = {
        "positions": positions.astype(float),
        "progress": run.progress[..., None].astype(np.int64),
        "waiting": run.waiting[..., None],
        "plan": np.transpose(traj.positions, (1, 0, 2)).copy(),
    }
    return Trace("coordination", arrays, run.events, metadata, results, workspace)


def check(spec: Spec):
    """Plan (or load) a scenario's trajectories and check Definition 4 and Theorem 4's condition.

    Returns ``(trajectories, coordination_space, TheoryReport)``.
    """
    from .theory import check_theory

    traj = build_plan(spec)
    space = build_coordination_space(traj)
    return traj, space, check_theory(traj, space)
