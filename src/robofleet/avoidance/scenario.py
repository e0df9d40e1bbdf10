"""Scenario files of the avoidance family (paper 003): validated spec and ``simulate``.

Example (YAML)::

    family: avoidance
    method: buavc            # buavc | bvc | bvc_inflated
    delta: 0.1
    workspace:
      bounds: [-5, -5, 5, 5]            # xmin, ymin, xmax, ymax, or a list of [x, y] vertices
      obstacles: [{center: [-4, 1], size: [1, 1]}]
      obstacle_sigma: 0.1
    robots:
      n: 5
      radius: 0.2
      v_max: 0.4
      sigma: 0.1
      layout: {kind: antipodal, r_min: 0.3, r_max: 4.7}
"""

from __future__ import annotations

from typing import Literal, Optional, Union

import numpy as np
from pydantic import Field, field_validator, model_validator
from shapely.geometry import Polygon

from ..core import geometry
from ..core.errors import ScenarioError
from ..core.workspace import Workspace
from ..core.config import SpecModel
from .models_spec import ModelSpec, OrcaParams, Space3DSpec, TeamSpec, check_models, reject_3d_obstacles_in_2d

Point = tuple[float, float]


class ObstacleSpec(SpecModel):
    """A convex polygonal obstacle: a box (``center``, ``size``, ``yaw``) or ``vertices``."""

    center: Optional[Point] = None
    size: Optional[tuple[float, float]] = None
    yaw: float = 0.0
    vertices: Optional[list[Point]] = None

    @model_validator(mode="after")
    def _shape(self):
        if (self.vertices is None) == (self.center is None):
            raise ScenarioError("", "either 'center' and 'size' (a box) or 'vertices'", self.model_dump(exclude_none=True))
        if self.center is not None and (self.size is None or min(self.size) <= 0):
            raise ScenarioError("size", "two positive numbers", self.size)
        if self.vertices is not None:
            poly = Polygon(self.vertices)
            if len(self.vertices) < 3 or not poly.is_valid or poly.area <= 0:
                raise ScenarioError("vertices", "at least 3 points forming a simple polygon", self.vertices)
            if not np.isclose(poly.convex_hull.area, poly.area):
                raise ScenarioError("vertices", "a convex polygon (split non-convex obstacles into convex parts)", self.vertices)
        return self

    def polygon(self) -> np.ndarray:
        if self.vertices is not None:
            return geometry.ensure_ccw(np.asarray(self.vertices, float))
        return geometry.box_vertices(self.center, self.size, self.yaw)


class WorkspaceSpec(SpecModel):
    """Convex bounds, convex obstacles, and the obstacles' position uncertainty Σ_o."""

    bounds: Union[tuple[float, float, float, float], list[Point]] = (-5.0, -5.0, 5.0, 5.0)
    obstacles: list[ObstacleSpec] = Field(default_factory=list)
    obstacle_sigma: float = Field(0.0, ge=0.0)
    obstacle_cov: Optional[list[list[float]]] = None

    @field_validator("obstacle_cov")
    @classmethod
    def _cov(cls, v):
        return None if v is None else _check_cov(v).tolist()

    @model_validator(mode="after")
    def _bounds(self):
        if len(self.bounds) == 4 and not isinstance(self.bounds[0], (list, tuple)):
            x0, y0, x1, y1 = self.bounds
            if not (x0 < x1 and y0 < y1):
                raise ScenarioError("bounds", "[xmin, ymin, xmax, ymax] with min < max", list(self.bounds))
        verts = self.bounds_vertices()
        poly = Polygon(verts)
        if not poly.is_valid or poly.area <= 0:
            raise ScenarioError("bounds", "[xmin, ymin, xmax, ymax] with min < max, or a simple polygon", self.bounds)
        if not np.isclose(poly.convex_hull.area, poly.area):
            raise ScenarioError("bounds", "a convex polygon (B-UAVC cells are convex)", self.bounds)
        return self

    def bounds_vertices(self) -> np.ndarray:
        if len(self.bounds) == 4 and not isinstance(self.bounds[0], (list, tuple)):
            x0, y0, x1, y1 = self.bounds
            return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)
        return geometry.ensure_ccw(np.asarray(self.bounds, float))

    def obstacle_covariance(self) -> np.ndarray:
        return np.asarray(self.obstacle_cov, float) if self.obstacle_cov is not None else self.obstacle_sigma**2 * np.eye(2)

    def build(self) -> Workspace:
        return Workspace(self.bounds_vertices(), tuple(o.polygon() for o in self.obstacles))


class LayoutSpec(SpecModel):
    """Start and goal layout: ``circle`` (goal = −start), ``antipodal`` (random, the
    authors' setup) or ``explicit`` lists."""

    kind: Literal["circle", "antipodal", "explicit"] = "circle"
    radius: float = Field(4.0, gt=0)
    r_min: float = Field(0.3, ge=0)
    r_max: float = Field(4.7, gt=0)
    center: Point = (0.0, 0.0)
    starts: Optional[list[Point]] = None
    goals: Optional[list[Point]] = None

    @model_validator(mode="after")
    def _fields(self):
        if self.kind == "explicit":
            if self.starts is None or self.goals is None:
                raise ScenarioError("starts", "'starts' and 'goals' lists for an explicit layout", None)
            if len(self.starts) != len(self.goals):
                raise ScenarioError("goals", f"{len(self.starts)} goals (one per start)", f"{len(self.goals)} goals")
        if self.r_min >= self.r_max:
            raise ScenarioError("r_min", f"a value below r_max = {self.r_max}", self.r_min)
        return self


class RobotsSpec(SpecModel):
    """The team: count, radius r_s, speed limit, localisation covariance Σ."""

    n: int = Field(5, ge=1, le=1_000_000)
    radius: float = Field(0.2, gt=0)
    v_max: float = Field(0.4, gt=0)
    sigma: float = Field(0.1, ge=0)
    cov: Optional[list[list[float]]] = None
    layout: LayoutSpec = Field(default_factory=LayoutSpec)

    @field_validator("cov")
    @classmethod
    def _cov(cls, v):
        return None if v is None else _check_cov(v).tolist()

    def covariance(self) -> np.ndarray:
        return np.asarray(self.cov, float) if self.cov is not None else self.sigma**2 * np.eye(2)


class DeadlockSpec(SpecModel):
    """Deadlock heuristic of appendix C (see :mod:`robofleet.avoidance.controller`)."""

    enabled: bool = True
    window: int = Field(20, ge=1)
    progress_fraction: float = Field(0.25, gt=0, lt=1)
    recover_steps: int = Field(10, ge=1)


class Spec(SpecModel):
    """A B-UAVC scenario: single-integrator robots in 2D by default; ``model``, ``teams``,
    ``space3d`` and ``method: orca`` select the other models of paper 003
    (:mod:`robofleet.avoidance.models_spec`)."""

    family: Literal["avoidance"] = "avoidance"
    name: str = ""
    method: Literal["buavc", "bvc", "bvc_inflated", "orca"] = "buavc"
    delta: float = Field(0.1, gt=0, lt=1)
    inflation_sigmas: float = Field(3.0, ge=0)
    local_box: float = Field(2.0, gt=0)
    dt: float = Field(0.1, gt=0)
    max_steps: int = Field(500, ge=1)
    goal_tolerance: float = Field(0.1, gt=0)
    workspace: WorkspaceSpec = Field(default_factory=WorkspaceSpec)
    robots: RobotsSpec = Field(default_factory=RobotsSpec)
    deadlock: DeadlockSpec = Field(default_factory=DeadlockSpec)
    record_cells: Optional[bool] = None
    model: ModelSpec = Field(default_factory=ModelSpec)
    orca: OrcaParams = Field(default_factory=OrcaParams)
    space3d: Optional[Space3DSpec] = None
    teams: Optional[list[TeamSpec]] = None

    @model_validator(mode="before")
    @classmethod
    def _no_3d_obstacles_in_2d(cls, data):
        return reject_3d_obstacles_in_2d(data)

    @model_validator(mode="after")
    def _layout_fits(self):
        if not self.teams:
            check_layout(self)
        check_models(self)
        return self

    @property
    def uses_models(self) -> bool:
        """Whether the run needs the general-model loop (:mod:`.models_simulation`)."""
        return self.method == "orca" or not self.model.is_default or self.space3d is not None or bool(self.teams)


def _check_cov(value) -> np.ndarray:
    cov = np.asarray(value, float) if np.ndim(value) == 2 else None
    if cov is None or cov.shape != (2, 2) or not np.all(np.isfinite(cov)):
        raise ScenarioError("", "a 2×2 matrix of finite numbers", value)
    if not np.allclose(cov, cov.T, atol=1e-12):
        raise ScenarioError("", "a symmetric matrix", value)
    if np.linalg.eigvalsh(cov).min() < -1e-12:
        raise ScenarioError("", "a positive semi-definite matrix (eigenvalues ≥ 0)", value)
    return cov


def check_layout(spec: Spec) -> None:
    """Reject layouts whose starts or goals overlap, leave the workspace, hit an obstacle,
    or cannot fit N robots."""
    r, n, lay = spec.robots.radius, spec.robots.n, spec.robots.layout
    if lay.kind == "explicit":
        if len(lay.starts) != n:
            raise ScenarioError("robots.layout.starts", f"{n} starts (robots.n)", f"{len(lay.starts)} starts")
    elif lay.kind == "circle":
        if n > 1 and 2 * lay.radius * np.sin(np.pi / n) < 2 * r:
            most = int(np.pi / np.arcsin(min(1.0, r / lay.radius)))
            raise ScenarioError("robots.n", f"at most {most} robots of radius {r} on a circle of radius {lay.radius}", n)
    else:
        ring = np.pi * (lay.r_max**2 - lay.r_min**2)
        if n * np.pi * (2 * r) ** 2 > 0.5 * ring or (n > 1 and 2 * np.pi * lay.r_max / n < 2 * r):
            raise ScenarioError("robots.n", f"few enough robots of radius {r} to fit in the ring r ∈ [{lay.r_min}, {lay.r_max}]", n)
        return
    starts, goals = fixed_layout(spec)
    ws = spec.workspace.build()
    for name, pts in (("starts", starts), ("goals", goals)):
        _check_points(f"robots.layout.{name}", pts, r, ws)


def _check_points(field: str, pts: np.ndarray, r: float, ws: Workspace) -> None:
    pairs = geometry.close_pairs(pts, 2 * r)
    if len(pairs):
        i, j = pairs[0]
        raise ScenarioError(f"{field}[{i}]", f"robots at least 2·radius = {2 * r} apart", f"{pts[i].tolist()} overlaps robot {j} at {pts[j].tolist()}")
    inside = ws.boundary_distance(pts)
    bad = np.flatnonzero(inside < r)
    if len(bad):
        raise ScenarioError(f"{field}[{bad[0]}]", f"a point at least radius {r} inside the workspace", pts[bad[0]].tolist())
    clear = ws.obstacle_distance(pts)
    bad = np.flatnonzero(clear < r)
    if len(bad):
        raise ScenarioError(f"{field}[{bad[0]}]", f"a point at least radius {r} from every obstacle", pts[bad[0]].tolist())


def fixed_layout(spec: Spec) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals of a deterministic layout (circle or explicit)."""
    lay, n = spec.robots.layout, spec.robots.n
    if lay.kind == "explicit":
        return np.asarray(lay.starts, float), np.asarray(lay.goals, float)
    angle = 2 * np.pi * np.arange(n) / n
    starts = lay.radius * np.column_stack([np.cos(angle), np.sin(angle)])
    return starts + lay.center, -starts + lay.center


def start_clearances(spec: Spec) -> tuple[float, float, float]:
    """Centre distances a sampled start or goal keeps from other robots, obstacles and the
    bounds so that it lies inside its own initial B-UAVC (the premise of the guarantee).

    Robots: ``2 (r_s + Φ⁻¹(√(1 − δ)) σ)``; obstacles: ``r_s + Φ⁻¹(√(1 − δ)) σ + r_ε σ_o``
    (r_ε the ε-shadow radius); bounds: ``r_s + Φ⁻¹(√(1 − δ)) σ`` — with σ, σ_o the largest
    standard deviations of Σ, Σ_o. They depend on the scenario's noise and δ, not on the
    method, so every method of a comparison starts from the same positions.
    """
    from scipy.stats import chi2
    from scipy.special import ndtri

    q = float(ndtri(np.sqrt(1.0 - spec.delta)))
    sigma = float(np.sqrt(max(np.linalg.eigvalsh(spec.robots.covariance()).max(), 0.0)))
    sigma_o = float(np.sqrt(max(np.linalg.eigvalsh(spec.workspace.obstacle_covariance()).max(), 0.0)))
    eps = 1.0 - np.sqrt(1.0 - spec.delta)
    own = spec.robots.radius + q * sigma
    return 2 * own, own + float(np.sqrt(chi2.ppf(1.0 - eps, 2))) * sigma_o, own


def sample_layout(spec: Spec, rng: np.random.Generator, max_tries: int = 10_000) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals: fixed layouts as given; ``antipodal`` sampled as in the authors'
    setup (robot i at a random angle within its own sector of width 2π/n, radius
    U(r_min, r_max), goal = −start), rejection-sampled robot by robot so that every start
    and goal keeps the clearances of :func:`start_clearances` from the others, the
    obstacles and the bounds."""
    lay, n = spec.robots.layout, spec.robots.n
    if lay.kind != "antipodal":
        return fixed_layout(spec)
    robot_gap, obstacle_gap, wall_gap = start_clearances(spec)
    ws = spec.workspace.build()
    center = np.asarray(lay.center)
    starts = np.zeros((n, 2))
    for i in range(n):
        for _ in range(max_tries):
            ang = 2 * np.pi * (i + rng.random()) / n
            rad = rng.uniform(lay.r_min, lay.r_max)
            s = rad * np.array([np.cos(ang), np.sin(ang)])
            cand = np.array([center + s, center - s])
            prev = np.vstack([center + starts[:i], center - starts[:i]])
            if len(prev) and np.min(np.linalg.norm(prev[:, None] - cand[None], axis=-1)) < robot_gap:
                continue
            if np.min(ws.boundary_distance(cand)) < wall_gap or np.min(ws.obstacle_distance(cand)) < obstacle_gap:
                continue
            starts[i] = s
            break
        else:
            raise ScenarioError("robots.layout", f"room for robot {i} after {max_tries} tries (fewer robots or a larger ring)", n)
    return center + starts, center - starts


def simulate(spec: Spec, seed=None, progress: bool = False):
    """Run the scenario; see :func:`robofleet.avoidance.simulation.run`."""
    from .simulation import run

    return run(spec, seed=seed, progress=progress)
