"""Scenario blocks for the robot models of paper 003 beyond the 2-D single integrator:
robot model and controller, ORCA parameters, 3-D workspaces with yawed boxes, and
heterogeneous teams (ground robots and quadrotors).

Example (a 3-D quadrotor swap)::

    method: buavc
    dt: 0.05
    space3d:
      bounds: [-5, -5, 0, 5, 5, 3]
      boxes: [{center: [0, 0, 1.5], size: [1, 1, 3], yaw: 0.3}]
      obstacle_sigma: 0.05
    teams:
      - model: {kind: quadrotor, controller: mpc, mpc: {horizon: 20}}
        n: 4
        v_max: 1.0
        sigma: 0.05
        layout: {kind: circle, radius: 3.5, height: 1.5}
"""

from __future__ import annotations

from typing import Literal, Optional

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..core.errors import ScenarioError
from ..dynamics.quadrotor import QuadrotorParams
from ..core.config import SpecModel
from .mpc import MPCConfig
from .orca import OrcaParams

ModelKind = Literal["single_integrator", "double_integrator", "unicycle", "quadrotor"]
Point2 = tuple[float, float]
Point3 = tuple[float, float, float]


class ModelSpec(SpecModel):
    """A robot model, its parameters and its controller.

    ``double_integrator`` needs ``a_max``; ``unicycle`` needs ``omega_max``;
    ``quadrotor`` takes the appendix-D parameters under ``quadrotor`` (defaults: the
    identified Bebop 2 values) and needs ``controller: mpc``. The speed limit ``v_max``
    is the team's (``robots.v_max``).
    """

    kind: ModelKind = "single_integrator"
    controller: Literal["one_step", "mpc"] = "one_step"
    a_max: Optional[float] = Field(None, gt=0)
    omega_max: Optional[float] = Field(None, gt=0)
    quadrotor: QuadrotorParams = Field(default_factory=QuadrotorParams)
    mpc: MPCConfig = Field(default_factory=MPCConfig)

    @model_validator(mode="after")
    def _required(self):
        if self.kind == "double_integrator" and self.a_max is None:
            raise ScenarioError("a_max", "a number > 0 (required by model double_integrator)", None)
        if self.kind == "unicycle" and self.omega_max is None:
            raise ScenarioError("omega_max", "a number > 0 (required by model unicycle)", None)
        if self.kind == "quadrotor" and self.controller != "mpc":
            raise ScenarioError("controller", "'mpc' (the quadrotor has no one-step controller)", self.controller)
        return self

    @property
    def is_default(self) -> bool:
        return self.kind == "single_integrator" and self.controller == "one_step"


class Box3DSpec(SpecModel):
    """A box obstacle ``size`` at ``center`` rotated by ``yaw`` about z."""

    center: Point3
    size: tuple[float, float, float]
    yaw: float = 0.0

    @field_validator("center", "size", mode="before")
    @classmethod
    def _three(cls, value, info):
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise ScenarioError("", "three numbers [x, y, z]" if info.field_name == "center" else "three side lengths", value)
        return value

    @model_validator(mode="after")
    def _size(self):
        if min(self.size) <= 0:
            raise ScenarioError("size", "three positive numbers", list(self.size))
        return self


class Space3DSpec(SpecModel):
    """A 3-D workspace box ``[xmin, ymin, zmin, xmax, ymax, zmax]`` with box obstacles."""

    bounds: tuple[float, float, float, float, float, float] = (-5.0, -5.0, 0.0, 5.0, 5.0, 3.0)
    boxes: list[Box3DSpec] = Field(default_factory=list)
    obstacle_sigma: float = Field(0.0, ge=0.0)

    @model_validator(mode="after")
    def _order(self):
        lo, hi = np.array(self.bounds[:3]), np.array(self.bounds[3:])
        if np.any(lo >= hi):
            raise ScenarioError("bounds", "[xmin, ymin, zmin, xmax, ymax, zmax] with min < max", list(self.bounds))
        return self

    @property
    def lower(self) -> np.ndarray:
        return np.array(self.bounds[:3], float)

    @property
    def upper(self) -> np.ndarray:
        return np.array(self.bounds[3:], float)


class TeamLayoutSpec(SpecModel):
    """``circle``: robots evenly on a circle (goal = the antipode), at ``height`` in 3-D,
    starting at angle ``phase``; ``explicit``: ``starts``/``goals`` lists."""

    kind: Literal["circle", "explicit"] = "circle"
    radius: float = Field(3.0, gt=0)
    height: float = 1.0
    phase: float = 0.0
    starts: Optional[list[list[float]]] = None
    goals: Optional[list[list[float]]] = None

    @model_validator(mode="after")
    def _explicit(self):
        if self.kind == "explicit":
            if self.starts is None or self.goals is None or len(self.starts) != len(self.goals):
                raise ScenarioError("starts", "'starts' and 'goals' lists of equal length for an explicit layout", None)
        return self


class TeamSpec(SpecModel):
    """A group of identical robots in a heterogeneous team (all share ``robots.radius``)."""

    name: str = ""
    model: ModelSpec = Field(default_factory=ModelSpec)
    n: int = Field(1, ge=1, le=10_000)
    v_max: float = Field(0.4, gt=0)
    sigma: float = Field(0.0, ge=0)
    layout: TeamLayoutSpec = Field(default_factory=TeamLayoutSpec)

    @property
    def flying(self) -> bool:
        return self.model.kind == "quadrotor"


def reject_3d_obstacles_in_2d(data):
    """Before validation: a 3-D box under ``workspace.obstacles`` gets a clear one-line error."""
    if not isinstance(data, dict):
        return data
    obstacles = (data.get("workspace") or {}).get("obstacles") if isinstance(data.get("workspace"), dict) else None
    for k, obs in enumerate(obstacles or []):
        if not isinstance(obs, dict):
            continue
        for key in ("center", "size"):
            value = obs.get(key)
            if isinstance(value, (list, tuple)) and len(value) == 3:
                raise ScenarioError(f"workspace.obstacles.{k}.{key}", "a 2D value [x, y] (3D boxes belong under space3d.boxes)", list(value))
    return data


def check_models(spec) -> None:
    """Cross-field checks of the model blocks of an avoidance ``Spec``."""
    teams = spec.teams or []
    if spec.space3d is not None:
        if spec.workspace.obstacles:
            raise ScenarioError("workspace.obstacles", "no 2D obstacles in a 3D scenario (use space3d.boxes)", len(spec.workspace.obstacles))
        if not teams:
            raise ScenarioError("teams", "a list of robot teams (3D scenarios describe robots per team)", None)
    for k, team in enumerate(teams):
        if team.flying and spec.space3d is None:
            raise ScenarioError(f"teams.{k}.model.kind", "a ground model in a 2D scenario (quadrotors need space3d)", team.model.kind)
    if spec.method == "orca":
        kinds = {t.model.kind for t in teams} | ({spec.model.kind} if not teams else set())
        if kinds != {"single_integrator"} or spec.space3d is not None:
            raise ScenarioError("method", "a B-UAVC method for non-holonomic, second-order or 3D robots (ORCA is for 2D single integrators)", "orca")
    if spec.model.kind == "quadrotor" and not teams:
        raise ScenarioError("model.kind", "a ground model for the 2D robots block (quadrotors need space3d and teams)", "quadrotor")
    if teams:
        _check_team_layouts(spec, teams)


def team_layouts(spec) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Starts and goals ``(N, d)`` of all teams, and each team's robot indices."""
    dim = 3 if spec.space3d is not None else 2
    starts, goals, index, offset = [], [], [], 0
    for team in spec.teams:
        lay = team.layout
        if lay.kind == "explicit":
            s, g = _explicit_points(lay.starts, dim, team), _explicit_points(lay.goals, dim, team)
        else:
            ang = lay.phase + 2 * np.pi * np.arange(team.n) / team.n
            s = np.zeros((team.n, dim))
            s[:, 0], s[:, 1] = lay.radius * np.cos(ang), lay.radius * np.sin(ang)
            g = s.copy()
            g[:, :2] *= -1
            if dim == 3:
                s[:, 2] = g[:, 2] = lay.height if team.flying else ground_height(spec)
        starts.append(s), goals.append(g), index.append(np.arange(offset, offset + len(s)))
        offset += len(s)
    return np.concatenate(starts), np.concatenate(goals), index


def ground_height(spec) -> float:
    """Height of the centres of ground robots in a 3-D scenario: the floor plus their radius."""
    return float(spec.space3d.lower[2] + spec.robots.radius)


def _explicit_points(points, dim, team) -> np.ndarray:
    pts = np.asarray(points, float)
    want = 3 if (dim == 3 and team.flying) else 2
    if pts.ndim != 2 or pts.shape[1] != want:
        raise ScenarioError("layout.starts", f"points of {want} numbers for a {team.model.kind} team", points)
    if dim == 3 and want == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    return pts


def _check_team_layouts(spec, teams) -> None:
    from ..core import geometry

    for k, team in enumerate(teams):
        if team.layout.kind == "explicit" and len(team.layout.starts) != team.n:
            raise ScenarioError(f"teams.{k}.layout.starts", f"{team.n} starts (teams.{k}.n)", f"{len(team.layout.starts)} starts")
    try:
        starts, goals, _ = team_layouts(spec)
    except ScenarioError as exc:
        raise ScenarioError(f"teams.{exc.field}", exc.expected, exc.received) from None
    r = spec.robots.radius
    for name, pts in (("starts", starts), ("goals", goals)):
        pairs = geometry.close_pairs(pts, 2 * r)
        if len(pairs):
            i, j = pairs[0]
            raise ScenarioError(f"teams.layout.{name}[{i}]", f"robots at least 2·radius = {2 * r} apart", f"{pts[i].tolist()} overlaps robot {j}")
        lo, hi = _bounds(spec)
        bad = np.flatnonzero(np.any(pts[:, : len(lo)] < lo + r - 1e-9, axis=1) | np.any(pts[:, : len(lo)] > hi - r + 1e-9, axis=1))
        if len(bad):
            raise ScenarioError(f"teams.layout.{name}[{bad[0]}]", f"a point at least radius {r} inside the workspace", pts[bad[0]].tolist())


def _bounds(spec):
    if spec.space3d is not None:
        lo, hi = spec.space3d.lower.copy(), spec.space3d.upper.copy()
        lo[2] = min(lo[2], ground_height(spec) - spec.robots.radius)
        return lo, hi
    v = spec.workspace.bounds_vertices()
    return v.min(axis=0), v.max(axis=0)


__all__ = ["ModelSpec", "Box3DSpec", "Space3DSpec", "TeamSpec", "TeamLayoutSpec", "OrcaParams", "check_models", "team_layouts", "reject_3d_obstacles_in_2d"]
