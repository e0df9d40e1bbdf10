"""Scenario files of the avoidance family (Zhu et al. 2022, B-UAVC): the one validated ``Spec``.

A scenario describes one or more *teams* of robots sharing a safety radius ``r_s``. The
2-D single-integrator team of the authors' main setup is written with the short
``robots:`` (+ optional ``model:``) blocks; every other setup (double integrators,
differential-drive robots, quadrotors, heterogeneous teams, 3-D workspaces) lists
``teams:``. Both spellings are normalised into the same team representation
(:meth:`Spec.team_specs`), which is all the simulation reads.

Example (a 2-D team, short form)::

    family: avoidance
    method: buavc            # buavc | bvc | bvc_inflated | orca
    delta: 0.1
    workspace:
      bounds: [-5, -5, 5, 5]            # xmin, ymin, xmax, ymax, or a convex polygon
      obstacles: [{center: [-4, 1], size: [1, 1]}]
      obstacle_sigma: 0.1
    robots:
      n: 5
      radius: 0.2
      v_max: 0.4
      sigma: 0.1
      layout: {kind: antipodal, r_min: 0.3, r_max: 4.7}

Example (3-D quadrotors, teams)::

    method: buavc
    dt: 0.05
    robots: {radius: 0.2}
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

import math

from collections.abc import Sequence
from typing import Any, Literal, Optional

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..core import extras, geometry
from ..core.budget import RunSize
from ..core.config import SpecModel
from ..core.errors import ScenarioError
from ..core.spec_blocks import RecordingSpec, WorkspaceSpec, is_convex
from ..core.workspace import Workspace
from ..dynamics.quadrotor import QuadrotorParams
from .buffer import MIN_DELTA, confidence_quantile, shadow_epsilon
from .cell3d import shadow_radius
from .controller_params import MPCConfig, OrcaParams
from .navigation.params import (LIVENESS_PLACES, BandParams, DetourParams, NavigationParams, RightHandParams, RouteParams,
                                YieldingParams)
from .placement import halves_points, longest_halves_trip

Point = tuple[float, float]
Point3 = tuple[float, float, float]
ModelKind = Literal["single_integrator", "double_integrator", "unicycle", "quadrotor"]
Method = Literal["buavc", "bvc", "bvc_inflated", "orca"]
MPC_STAGE_ROWS = 12
"""Rows of one MPC stage besides the cell's (dynamics, input and state bounds), for the memory budget."""
MPC_ROW_BYTES = 4096
"""Memory of one MPC constraint row of one stage (symbolic expression, Jacobian, solver), for the memory budget."""
LEGACY_TEAM = "robots"
"""Name of the team the short ``robots:`` + ``model:`` blocks describe."""


# ---------------------------------------------------------------------------------------
# workspace
# ---------------------------------------------------------------------------------------
class AvoidanceWorkspaceSpec(WorkspaceSpec):
    """The shared ``workspace:`` vocabulary, tightened to what B-UAVC cells need and
    extended by the obstacles' position uncertainty Σ_o (appendix A).

    Bounds and obstacles must be convex: every cell is an intersection of half-planes,
    one per wall of the (convex) bounds and one per (convex) obstacle's ε-shadow.
    ``obstacle_cov`` (a 2×2 matrix) wins over ``obstacle_sigma`` (Σ_o = σ_o² I).
    """

    obstacle_sigma: float = Field(0.0, ge=0.0)
    obstacle_cov: Optional[list[list[float]]] = None

    @field_validator("obstacle_cov")
    @classmethod
    def _cov(cls, value):
        return None if value is None else checked_covariance(value).tolist()

    @model_validator(mode="after")
    def _convex(self):
        if not is_convex(self.bounds_vertices()):
            raise ScenarioError("bounds", "a convex polygon (B-UAVC cells are convex)", self.bounds)
        for k, obstacle in enumerate(self.obstacles):
            if obstacle.vertices is not None and not is_convex(obstacle.polygon()):
                raise ScenarioError(f"obstacles.{k}.vertices", "a convex polygon (split non-convex obstacles into convex parts)", obstacle.vertices)
        return self

    def obstacle_covariance(self) -> np.ndarray:
        """Σ_o ``(2, 2)`` of every obstacle's position."""
        return np.asarray(self.obstacle_cov, float) if self.obstacle_cov is not None else self.obstacle_sigma**2 * np.eye(2)


def checked_covariance(value: Any) -> np.ndarray:
    """``value`` as a symmetric positive semi-definite 2×2 matrix, or a :class:`ScenarioError`."""
    cov = np.asarray(value, float) if np.ndim(value) == 2 else None
    if cov is None or cov.shape != (2, 2) or not np.all(np.isfinite(cov)):
        raise ScenarioError("", "a 2×2 matrix of finite numbers", value)
    if not np.allclose(cov, cov.T, atol=1e-12):
        raise ScenarioError("", "a symmetric matrix", value)
    if np.linalg.eigvalsh(cov).min() < -1e-12:
        raise ScenarioError("", "a positive semi-definite matrix (eigenvalues ≥ 0)", value)
    return cov


def checked_robot_covariances(value: Any) -> list:
    """``robots.cov`` / ``teams.k.cov``: one 2×2 matrix shared by the robots, or a list of
    one matrix per robot, each symmetric PSD (the error names the robot index)."""
    if not per_robot(value):
        return checked_covariance(value).tolist()
    out = []
    for i, matrix in enumerate(value):
        try:
            out.append(checked_covariance(matrix).tolist())
        except ScenarioError as exc:
            raise ScenarioError(str(i), f"{exc.expected} for robot {i}", matrix) from None
    return out


def per_robot(value: Any) -> bool:
    """Whether a ``cov`` value lists one matrix per robot (its entries' rows are lists)."""
    return isinstance(value, (list, tuple)) and len(value) > 0 and all(
        isinstance(m, (list, tuple)) and len(m) > 0 and isinstance(m[0], (list, tuple)) for m in value)


def robot_covariances(cov: Optional[list], sigma: float, n: int) -> np.ndarray:
    """Σ of the robots' planar estimates: ``(2, 2)`` when all robots share it (σ² I, one
    matrix, or a per-robot list of equal matrices, so the shared closed form applies),
    else ``(n, 2, 2)``, one per robot."""
    if cov is None:
        return sigma**2 * np.eye(2)
    covs = np.asarray(cov, float)
    if covs.ndim == 3 and np.all(covs == covs[0]):
        return covs[0].copy()
    return covs


def check_covariance_count(field: str, cov: Optional[list], n: int) -> None:
    """A per-robot ``cov`` list has one matrix per robot."""
    if cov is not None and per_robot(cov) and len(cov) != n:
        raise ScenarioError(field, f"one 2×2 matrix, or {n} matrices (one per robot)", f"{len(cov)} matrices")


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
    """A 3-D workspace box ``[xmin, ymin, zmin, xmax, ymax, zmax]`` with box obstacles
    whose positions are uncertain (Σ_o = ``obstacle_sigma``\\ ² I)."""

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

    def box_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Centres ``(O, 3)``, sizes ``(O, 3)`` and yaws ``(O,)`` of the boxes."""
        centers = np.array([b.center for b in self.boxes], float).reshape(-1, 3)
        sizes = np.array([b.size for b in self.boxes], float).reshape(-1, 3)
        return centers, sizes, np.array([b.yaw for b in self.boxes], float)


# ---------------------------------------------------------------------------------------
# robot models and teams
# ---------------------------------------------------------------------------------------
class ModelSpec(SpecModel):
    """A robot model, its parameters and its controller.

    ``double_integrator`` needs ``a_max``; ``unicycle`` needs ``omega_max``;
    ``quadrotor`` takes the appendix-D parameters under ``quadrotor`` (defaults: the
    identified Bebop 2 values) and needs ``controller: mpc``. The speed limit ``v_max``
    is the team's.
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
        if self.controller == "mpc" and extras.missing("mpc"):
            raise ScenarioError("controller", f"{extras.expectation('mpc')} for controller 'mpc'", "mpc")
        return self

    @property
    def has_heading(self) -> bool:
        """Whether the state carries a heading (unicycle θ, quadrotor yaw ψ)."""
        return self.kind in ("unicycle", "quadrotor")


class TeamLayoutSpec(SpecModel):
    """Starts and goals of a team: ``circle`` (robots evenly on a circle of ``radius``
    about ``center`` from angle ``phase``, goal = the antipode; at ``height`` in 3-D),
    ``halves`` (robots fill the two halves of ``box`` on a grid of pitch ``spacing`` and
    swap, :mod:`.placement`) or ``explicit`` ``starts``/``goals`` lists."""

    kind: Literal["circle", "halves", "explicit"] = "circle"
    radius: float = Field(3.0, gt=0)
    center: Point = (0.0, 0.0)
    phase: float = 0.0
    height: float = 1.0
    box: Optional[tuple[float, float, float, float]] = Field(None, description="area [xmin, ymin, xmax, ymax] whose left and right halves a `halves` layout fills [m]")
    spacing: float = Field(0.6, gt=0, description="grid pitch of a `halves` layout, at least 2 r_s [m]")
    starts: Optional[list[list[float]]] = None
    goals: Optional[list[list[float]]] = None

    def longest_trip(self) -> float:
        """The longest straight start–goal distance this layout can give [m]."""
        if self.kind == "antipodal":
            return 2.0 * self.r_max
        if self.kind == "circle":
            return 2.0 * self.radius
        if self.kind == "halves":
            return longest_halves_trip(self.box, self.spacing)
        return float(max(np.linalg.norm(np.subtract(g[:2], s[:2])) for s, g in zip(self.starts, self.goals)))

    @model_validator(mode="after")
    def _fields(self):
        if self.kind == "explicit":
            if self.starts is None or self.goals is None or len(self.starts) != len(self.goals):
                raise ScenarioError("starts", "'starts' and 'goals' lists of equal length for an explicit layout", None)
        if self.kind == "halves" and (self.box is None or not (self.box[0] < self.box[2] and self.box[1] < self.box[3])):
            raise ScenarioError("box", "[xmin, ymin, xmax, ymax] with min < max for a halves layout", None if self.box is None else list(self.box))
        return self


class LayoutSpec(TeamLayoutSpec):
    """The ``robots.layout`` block: a team layout (circle of radius 4 m by default,
    explicit) or ``antipodal`` (random, the authors' setup: robot i at a random angle in
    its own sector of width 2π/n, radius U(r_min, r_max), goal = −start)."""

    kind: Literal["circle", "antipodal", "halves", "explicit"] = "circle"
    radius: float = Field(4.0, gt=0)
    r_min: float = Field(0.3, ge=0)
    r_max: float = Field(4.7, gt=0)
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


class PlanarNoise(SpecModel):
    """What the ``robots:`` block and every ``teams:`` entry share: the count ``n`` and the
    localisation covariance of the planar estimates — ``cov`` (one 2×2 matrix, or a list
    of one per robot, each checked) or else ``sigma``\\ ² I."""

    n: int = Field(1, ge=1, le=1_000_000)
    sigma: float = Field(0.0, ge=0)
    cov: Optional[list] = None

    @field_validator("cov")
    @classmethod
    def _cov(cls, value):
        return None if value is None else checked_robot_covariances(value)

    @model_validator(mode="after")
    def _cov_count(self):
        check_covariance_count("cov", self.cov, self.n)
        return self

    def covariance(self) -> np.ndarray:
        """Σ: ``(2, 2)`` shared, or ``(n, 2, 2)`` per robot (:func:`robot_covariances`)."""
        return robot_covariances(self.cov, self.sigma, self.n)

    def largest_sigma(self) -> float:
        """The largest standard deviation of Σ (``√λ_max``, over all robots)."""
        return float(np.sqrt(max(np.linalg.eigvalsh(self.covariance()).max(), 0.0)))


class TeamSpec(PlanarNoise):
    """A group of identical robots (one model, one controller); all teams share
    ``robots.radius``. Localisation noise Σ = ``cov`` (2-D only; one matrix, or a list of
    one per robot) or ``sigma``\\ ² I."""

    name: str = ""
    model: ModelSpec = Field(default_factory=ModelSpec)
    n: int = Field(1, ge=1, le=1_000_000)
    v_max: float = Field(0.4, gt=0)
    sigma: float = Field(0.0, ge=0)
    layout: TeamLayoutSpec = Field(default_factory=TeamLayoutSpec)

    @property
    def flying(self) -> bool:
        return self.model.kind == "quadrotor"


class RobotsSpec(PlanarNoise):
    """The ``robots:`` block: the shared safety radius r_s, and (short form) one 2-D team:
    count, speed limit, localisation covariance Σ (``cov``: one 2×2 matrix, or a list of
    one per robot; else ``sigma``\\ ² I) and layout."""

    n: int = Field(5, ge=1, le=1_000_000)
    radius: float = Field(0.2, gt=0)
    v_max: float = Field(0.4, gt=0)
    sigma: float = Field(0.1, ge=0)
    layout: LayoutSpec = Field(default_factory=LayoutSpec)


class DeadlockSpec(SpecModel):
    """Deadlock heuristic of appendix C: the progress window (:mod:`robofleet.avoidance.navigation.progress`)
    and the recovery (:mod:`robofleet.avoidance.navigation.recovery`)."""

    enabled: bool = True
    window: int = Field(20, ge=1)
    progress_fraction: float = Field(0.25, gt=0, lt=1)
    recover_steps: int = Field(10, ge=1)


class RouteSpec(SpecModel):
    """The route stage (:mod:`robofleet.avoidance.navigation.route`): roadmap sub-goals
    around the obstacles, with passages and exit points."""

    enabled: bool = RouteParams.enabled
    passage_sigmas: float = Field(RouteParams.passage_sigmas, ge=0)
    node_factor: float = Field(RouteParams.node_factor, gt=1)
    sight_factor: float = Field(RouteParams.sight_factor, gt=0, lt=1)
    gap_factor: float = Field(RouteParams.gap_factor, ge=0)


class DetourSpec(SpecModel):
    """The detour stage (:mod:`robofleet.avoidance.navigation.detour`): blocked robots
    re-plan around neighbours that hold still (not unicycles)."""

    enabled: bool = DetourParams.enabled
    steps: int = Field(DetourParams.steps, ge=1)
    block_steps: int = Field(DetourParams.block_steps, ge=1)
    node_factor: float = Field(DetourParams.node_factor, gt=1)
    sight_factor: float = Field(DetourParams.sight_factor, gt=0, lt=1)


class YieldingSpec(SpecModel):
    """The yielding stage (:mod:`robofleet.avoidance.navigation.yielding`): arrived robots
    step aside for neighbours that wait to pass, and return."""

    enabled: bool = YieldingParams.enabled
    near: float = Field(YieldingParams.near, gt=0)
    linger_steps: int = Field(YieldingParams.linger_steps, ge=1)
    aside: float = Field(YieldingParams.aside, ge=0)
    max_aside: float = Field(YieldingParams.max_aside, ge=0)
    aside_turn: float = Field(YieldingParams.aside_turn, ge=-180, le=180)
    clear_steps: int = Field(YieldingParams.clear_steps, ge=1)
    max_yield_steps: int = Field(YieldingParams.max_yield_steps, ge=1)
    still_radius: float = Field(YieldingParams.still_radius, gt=0)
    still_steps: int = Field(YieldingParams.still_steps, ge=2)
    return_steps: int = Field(YieldingParams.return_steps, ge=1)
    parked_steps: int = Field(YieldingParams.parked_steps, ge=0)
    press: float = Field(YieldingParams.press, ge=0)


class RightHandSpec(SpecModel):
    """The right-hand stage (:mod:`robofleet.avoidance.navigation.right_hand`, not unicycles)."""

    angle: float = Field(RightHandParams.angle, ge=0, lt=90)
    face_near: float = Field(RightHandParams.face_near, ge=0)


class BandSpec(SpecModel):
    """The band-return stage (:mod:`robofleet.avoidance.navigation.band`)."""

    sigmas: float = Field(BandParams.sigmas, ge=0)


class NavigationSpec(SpecModel):
    """The navigation stages of 2-D and ground teams (:mod:`robofleet.avoidance.navigation`),
    one block per stage. On by default; ``enabled: false`` gives the paper's controller
    (appendix C alone, arrived robots hold)."""

    enabled: bool = NavigationParams.enabled
    route: RouteSpec = Field(default_factory=RouteSpec)
    detour: DetourSpec = Field(default_factory=DetourSpec)
    yielding: YieldingSpec = Field(default_factory=YieldingSpec)
    right_hand: RightHandSpec = Field(default_factory=RightHandSpec)
    band: BandSpec = Field(default_factory=BandSpec)


# ---------------------------------------------------------------------------------------
# the scenario
# ---------------------------------------------------------------------------------------
class Spec(RecordingSpec):
    """A B-UAVC scenario (Zhu et al. 2022): method, chance threshold δ, workspace (2-D
    ``workspace`` or 3-D ``space3d``) and teams (``robots`` + ``model``, or ``teams``)."""

    family: Literal["avoidance"] = "avoidance"
    name: str = ""
    method: Method = "buavc"
    delta: float = Field(0.1, gt=0, lt=1)
    inflation_sigmas: float = Field(3.0, ge=0)
    local_box: float = Field(2.0, gt=0)
    dt: float = Field(0.1, gt=0)
    max_steps: int = Field(500, ge=1)
    goal_tolerance: float = Field(0.1, gt=0)
    workspace: AvoidanceWorkspaceSpec = Field(default_factory=AvoidanceWorkspaceSpec)
    robots: RobotsSpec = Field(default_factory=RobotsSpec)
    deadlock: DeadlockSpec = Field(default_factory=DeadlockSpec)
    navigation: NavigationSpec = Field(default_factory=NavigationSpec)
    record_cells: Optional[bool] = None
    model: ModelSpec = Field(default_factory=ModelSpec)
    orca: OrcaParams = Field(default_factory=OrcaParams)
    space3d: Optional[Space3DSpec] = None
    teams: Optional[list[TeamSpec]] = None

    @field_validator("delta")
    @classmethod
    def _finite_quantile(cls, value):  # input validation: a smaller δ makes Φ⁻¹(√(1 − δ)) infinite
        if value < MIN_DELTA:
            raise ScenarioError("", f"a number in [{MIN_DELTA:g}, 1) (smaller ones make the quantile Φ⁻¹(√(1 − δ)) infinite)", value)
        return value

    @model_validator(mode="before")
    @classmethod
    def _no_3d_obstacles_in_2d(cls, data):
        return reject_3d_obstacles_in_2d(data)

    @model_validator(mode="before")
    @classmethod
    def _no_liveness_block(cls, data):
        return reject_liveness_block(data)

    @model_validator(mode="after")
    def _cross_checks(self):
        if not self.teams:
            check_layout(self)
        check_models(self)
        return self

    @property
    def dim(self) -> int:
        """Workspace dimension: 3 with ``space3d``, else 2."""
        return 3 if self.space3d is not None else 2

    def team_specs(self) -> tuple[TeamSpec, ...]:
        """Every team, the short ``robots:`` + ``model:`` form normalised into one
        :class:`TeamSpec` named ``"robots"`` (its layout a :class:`TeamLayoutSpec`
        unless it is the random ``antipodal`` one, which only this form has)."""
        if self.teams:
            return tuple(self.teams)
        r = self.robots
        layout = r.layout if r.layout.kind == "antipodal" else TeamLayoutSpec(**r.layout.model_dump(include=set(TeamLayoutSpec.model_fields)))
        return (TeamSpec(name=LEGACY_TEAM, model=self.model, n=r.n, v_max=r.v_max, sigma=r.sigma, cov=r.cov, layout=layout),)

    def team_slices(self) -> list[slice]:
        """Each team's robot indices, in order, as slices of the whole fleet."""
        out, start = [], 0
        for team in self.team_specs():
            out.append(slice(start, start + team.n))
            start += team.n
        return out

    def ground_height(self) -> float:
        """Height of the centres of ground robots in a 3-D scenario: the floor plus r_s."""
        return float(self.space3d.lower[2] + self.robots.radius)

    # -- memory budget (input validation, robofleet.core.budget) --------------------------
    def run_size(self) -> RunSize:
        """What a run records per robot and step: true position and estimate (d numbers
        each), controls (at most 4), a heading and three flags; 2-D runs that record cells
        (``record_cells``, by default up to 64 robots) add, twice (the log, then the
        arrays), a row of d + 1 numbers per obstacle, wall and neighbour in the local box
        (at most twice as many as robots of radius r_s packed 2 r_s apart fill it)."""
        n = sum(team.n for team in self.teams) if self.teams else self.robots.n
        d = self.dim
        per_robot = 8 * (2 * d + 4 + 1) + 3
        row_fields = ["record_every"]
        cells = self.record_cells if self.record_cells is not None else n <= 64
        if d == 2 and self.method != "orca" and cells:
            packed = 2 * math.ceil((self.local_box / self.robots.radius + 1) ** 2)
            rows = min(n - 1, packed) + len(self.workspace.obstacles) + len(self.workspace.bounds_vertices())
            per_robot += 2 * 8 * rows * (d + 1)
            row_fields += ["record_cells", "workspace"] + (["local_box", "robots.radius"] if packed < n - 1 else [])
        teams = self.team_specs() if not self.teams else self.teams
        mpc_teams = [(k, t) for k, t in enumerate(teams) if t.model.controller == "mpc"]
        window = max([self.deadlock.window] + [t.model.mpc.deadlock_steps for _, t in mpc_teams])
        mpc = sum(t.n * t.model.mpc.horizon * (t.model.mpc.max_constraints + MPC_STAGE_ROWS) for _, t in mpc_teams)
        extra = 8 * (2 + d) * window * n + MPC_ROW_BYTES * mpc
        robots_field = "teams.n" if self.teams else "robots.n"
        extra_fields = ["deadlock.window", robots_field]
        for k, _ in mpc_teams:
            model = f"teams.{k}.model" if self.teams else "model"
            extra_fields += [f"{model}.mpc.{name}" for name in ("horizon", "max_constraints", "deadlock_steps")]
        return RunSize(self.max_steps, n, per_robot, "max_steps", robots_field, extra, "deadlock windows and MPC problems",
                       ", ".join(extra_fields), record_every=self.record_every, row_fields=", ".join(row_fields))


# ---------------------------------------------------------------------------------------
# cross-field checks
# ---------------------------------------------------------------------------------------
def reject_liveness_block(data: Any) -> Any:
    """Before validation: a flat ``liveness:`` block gets a one-line error naming where each
    of its fields belongs under ``navigation:``."""
    if not isinstance(data, dict) or "liveness" not in data:
        return data
    old = data["liveness"]
    keys = list(old) if isinstance(old, dict) else []
    moves = ", ".join(f"liveness.{k} → navigation.{LIVENESS_PLACES[k]}" for k in keys if k in LIVENESS_PLACES)
    raise ScenarioError("liveness", "the `navigation:` block, one sub-block per stage" + (f" ({moves})" if moves else ""), old)


def reject_3d_obstacles_in_2d(data: Any) -> Any:
    """Before validation: a 3-D box under ``workspace.obstacles`` gets a clear one-line error."""
    if not isinstance(data, dict):
        return data
    obstacles = (data.get("workspace") or {}).get("obstacles") if isinstance(data.get("workspace"), dict) else None
    for k, obs in enumerate(obstacles if isinstance(obstacles, list) else []):
        if not isinstance(obs, dict):
            continue
        for key in ("center", "size"):
            value = obs.get(key)
            if isinstance(value, (list, tuple)) and len(value) == 3:
                raise ScenarioError(f"workspace.obstacles.{k}.{key}", "a 2D value [x, y] (3D boxes belong under space3d.boxes)", list(value))
    return data


def check_models(spec: Spec) -> None:
    """Cross-field checks of the model and team blocks."""
    teams = spec.teams or []
    if spec.space3d is not None:
        if spec.workspace.obstacles:
            raise ScenarioError("workspace.obstacles", "no 2D obstacles in a 3D scenario (use space3d.boxes)", len(spec.workspace.obstacles))
        if not teams:
            raise ScenarioError("teams", "a list of robot teams (3D scenarios describe robots per team)", None)
    for k, team in enumerate(teams):
        if team.flying and spec.space3d is None:
            raise ScenarioError(f"teams.{k}.model.kind", "a ground model in a 2D scenario (quadrotors need space3d)", team.model.kind)
        if team.cov is not None and spec.space3d is not None:
            raise ScenarioError(f"teams.{k}.cov", "no cov in a 3D scenario (sigma gives Σ = σ² I)", team.cov)
    if spec.method == "orca":
        kinds = {t.model.kind for t in spec.team_specs()}
        if kinds != {"single_integrator"} or spec.space3d is not None:
            raise ScenarioError("method", "a B-UAVC method for non-holonomic, second-order or 3D robots (ORCA is for 2D single integrators)", "orca")
    if spec.model.kind == "quadrotor" and not teams:
        raise ScenarioError("model.kind", "a ground model for the 2D robots block (quadrotors need space3d and teams)", "quadrotor")
    if teams:
        check_team_layouts(spec, teams)


def check_layout(spec: Spec) -> None:
    """Short form: reject layouts whose starts or goals overlap, leave the workspace, hit
    an obstacle, or cannot fit N robots."""
    r, n, lay = spec.robots.radius, spec.robots.n, spec.robots.layout
    if lay.kind == "explicit":
        if len(lay.starts) != n:
            raise ScenarioError("robots.layout.starts", f"{n} starts (robots.n)", f"{len(lay.starts)} starts")
    elif lay.kind == "circle":
        if n > 1 and 2 * lay.radius * np.sin(np.pi / n) < 2 * r:
            most = int(np.pi / np.arcsin(min(1.0, r / lay.radius)))
            raise ScenarioError("robots.n", f"at most {most} robots of radius {r} on a circle of radius {lay.radius}", n)
    elif lay.kind == "antipodal":
        ring = np.pi * (lay.r_max**2 - lay.r_min**2)
        if n * np.pi * (2 * r) ** 2 > 0.5 * ring or (n > 1 and 2 * np.pi * lay.r_max / n < 2 * r):
            raise ScenarioError("robots.n", f"few enough robots of radius {r} to fit in the ring r ∈ [{lay.r_min}, {lay.r_max}]", n)
        return
    starts, goals = team_points(spec.team_specs()[0], 2, 0.0)
    ws = spec.workspace.build()
    for name, pts in (("starts", starts), ("goals", goals)):
        check_points(f"robots.layout.{name}", pts, r, ws)


def check_points(field: str, pts: np.ndarray, r: float, ws: Workspace) -> None:
    """Points at least ``2 r`` apart, ``r`` inside the bounds and ``r`` from every obstacle
    (an overlap names the lowest-numbered robot that has one and the first robot it overlaps)."""
    pairs = geometry.close_pairs_in_cells(pts, 2 * r)
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


def check_team_layouts(spec: Spec, teams: list[TeamSpec]) -> None:
    """``teams:`` form: explicit layouts of the right length; all starts and goals at least
    ``2 r_s`` apart and ``r_s`` inside the workspace box."""
    for k, team in enumerate(teams):
        if team.layout.kind == "explicit" and len(team.layout.starts) != team.n:
            raise ScenarioError(f"teams.{k}.layout.starts", f"{team.n} starts (teams.{k}.n)", f"{len(team.layout.starts)} starts")
    try:
        starts, goals, _ = deterministic_layout(spec)
    except ScenarioError as exc:
        raise ScenarioError(f"teams.{exc.field}", exc.expected, exc.received) from None
    r = spec.robots.radius
    lo, hi = workspace_box(spec)
    for name, pts in (("starts", starts), ("goals", goals)):
        pairs = geometry.close_pairs_in_cells(pts, 2 * r)
        if len(pairs):
            i, j = pairs[0]
            raise ScenarioError(f"teams.layout.{name}[{i}]", f"robots at least 2·radius = {2 * r} apart", f"{pts[i].tolist()} overlaps robot {j}")
        bad = np.flatnonzero(np.any(pts[:, : len(lo)] < lo + r - 1e-9, axis=1) | np.any(pts[:, : len(lo)] > hi - r + 1e-9, axis=1))
        if len(bad):
            raise ScenarioError(f"teams.layout.{name}[{bad[0]}]", f"a point at least radius {r} inside the workspace", pts[bad[0]].tolist())


def workspace_box(spec: Spec) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners of the workspace's bounding box (3-D: the floor lowered to
    the ground robots' plane minus r_s)."""
    if spec.space3d is not None:
        lo, hi = spec.space3d.lower.copy(), spec.space3d.upper.copy()
        lo[2] = min(lo[2], spec.ground_height() - spec.robots.radius)
        return lo, hi
    v = spec.workspace.bounds_vertices()
    return v.min(axis=0), v.max(axis=0)


# ---------------------------------------------------------------------------------------
# starts and goals
# ---------------------------------------------------------------------------------------
def team_points(team: TeamSpec, dim: int, ground_z: float) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals ``(n, dim)`` of a deterministic (circle or explicit) team layout.

    Circle: ``s_k = c + ρ (cos φ_k, sin φ_k)``, ``φ_k = phase + 2πk/n``, goal ``c − ρ (cos φ_k,
    sin φ_k)`` (the antipode); in 3-D at ``height`` for quadrotors, ``ground_z`` otherwise.
    """
    lay = team.layout
    if lay.kind == "explicit":
        return explicit_points(lay.starts, dim, team), explicit_points(lay.goals, dim, team)
    starts, goals = np.zeros((team.n, dim)), np.zeros((team.n, dim))
    if lay.kind == "halves":
        starts[:, :2], goals[:, :2] = halves_points(team.n, lay.box, lay.spacing)
    else:
        angle = lay.phase + 2 * np.pi * np.arange(team.n) / team.n
        ring = lay.radius * np.column_stack([np.cos(angle), np.sin(angle)])
        center = np.asarray(lay.center, float)
        starts[:, :2], goals[:, :2] = ring + center, -ring + center
    if dim == 3:
        starts[:, 2] = goals[:, 2] = lay.height if team.flying else ground_z
    return starts, goals


def explicit_points(points: Sequence[Sequence[float]], dim: int, team: TeamSpec) -> np.ndarray:
    """Explicit starts or goals as ``(n, dim)``: quadrotors give ``[x, y, z]``, ground
    robots ``[x, y]`` (their plane's height is added in 3-D)."""
    pts = np.asarray(points, float)
    want = 3 if (dim == 3 and team.flying) else 2
    if pts.ndim != 2 or pts.shape[1] != want:
        raise ScenarioError("layout.starts", f"points of {want} numbers for a {team.model.kind} team", points)
    if dim == 3 and want == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    return pts


def deterministic_layout(spec: Spec) -> tuple[np.ndarray, np.ndarray, list[slice]]:
    """Starts and goals ``(N, d)`` of every team whose layout is not random, and each
    team's slice of the fleet."""
    ground_z = spec.ground_height() if spec.space3d is not None else 0.0
    points = [team_points(team, spec.dim, ground_z) for team in spec.team_specs()]
    return np.concatenate([s for s, _ in points]), np.concatenate([g for _, g in points]), spec.team_slices()


TRAVEL_TIME_MULTIPLE = {"single_integrator": 4.0, "double_integrator": 4.0, "unicycle": 8.0, "quadrotor": 4.0}
"""The step-budget rule of the shipped scenarios: ``max_steps`` is this multiple of the
longest straight-line travel time at v_max (the slowest team decides). Unicycles get
twice as long: the three-projection controller turns before it drives and slows down
near cell boundaries (measured: their mean travel time is about 2× the straight-line
time, against about 1.2× for single integrators)."""


def straight_line_budget(spec: Spec) -> int:
    """``max_steps`` by :data:`TRAVEL_TIME_MULTIPLE`: ``ceil(k · d_max / (v_max Δt))``
    over the teams, ``d_max`` the longest start–goal distance their layout can give."""
    steps = [TRAVEL_TIME_MULTIPLE[t.model.kind] * t.layout.longest_trip() / (t.v_max * spec.dt) for t in spec.team_specs()]
    return int(np.ceil(max(steps) - 1e-9))


def start_clearances(spec: Spec) -> tuple[float, float, float]:
    """Centre distances a sampled start or goal keeps from other robots, obstacles and the
    bounds so that it lies inside its own initial B-UAVC (the premise of the guarantee).

    Robots: ``2 (r_s + Φ⁻¹(√(1 − δ)) σ)``; obstacles: ``r_s + Φ⁻¹(√(1 − δ)) σ + r_ε σ_o``
    (``r_ε = √(χ²₂⁻¹(1 − ε))`` the ε-shadow radius of appendix A, Lemma 1); bounds:
    ``r_s + Φ⁻¹(√(1 − δ)) σ`` — with σ, σ_o the largest standard deviations of Σ, Σ_o.
    They depend on the scenario's noise and δ, not on the method, so every method of a
    comparison starts from the same positions.
    """
    q = confidence_quantile(spec.delta)
    sigma = max(team.largest_sigma() for team in spec.team_specs())
    sigma_o = float(np.sqrt(max(np.linalg.eigvalsh(spec.workspace.obstacle_covariance()).max(), 0.0)))
    own = spec.robots.radius + q * sigma
    return 2 * own, own + shadow_radius(shadow_epsilon(spec.delta), 2) * sigma_o, own
