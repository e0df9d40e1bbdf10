"""The closed loop of Zhu et al. 2022 for every robot model and team: spec → world → steps → Trace.

Every step (docs/theory/buavc.md "Noise"): each robot's position estimate is its TRUE position
plus a draw from ``N(0, Σ)`` (velocities, headings and attitudes are measured exactly),
and each obstacle's estimated position is its true position plus a draw from
``N(0, Σ_o)``; every robot builds its cell from those estimates, its team's controller
picks the input, and the TRUE states move with the team's dynamics. Collisions are
judged on true positions (:mod:`~robofleet.avoidance.metrics`).

Methods share this code path and differ only in what the cells use (:class:`MethodSetup`):

* ``buavc``: Σ, Σ_o and the chance buffers (δ) — the B-UAVC of Sec. 4;
* ``bvc``: Σ = Σ_o = 0, buffer r_s (Zhou et al. 2017);
* ``bvc_inflated``: Σ = Σ_o = 0 and radius ``r_s + k σ_max`` (k = ``inflation_sigmas``);
* ``orca``: no cells; ORCA velocities (van den Berg et al. 2011) for 2-D single integrators,
  with the obstacles and walls as RVO2 handles them (:mod:`.orca_obstacles`).

Controllers, per team: single integrators — the one-step controller with the deadlock
heuristic of appendix C (:mod:`.controller`); double integrators — the braking rule
(Sec. 5.2, :mod:`.braking`), whose robots' cell rows are built from their braking segments
(:mod:`.segment_cells`, :meth:`World.braking_stops`); differential-drive robots — three projections (Sec. 5.3,
:mod:`.diff_drive`); quadrotors, and any model with ``controller: mpc`` — the B-UAVC MPC
(Sec. 5.4, :mod:`.mpc`).

In a 3-D space every robot's cell is built in R³ from all estimates; ground robots
(every model but the quadrotor) move in the plane ``z = z_g`` (floor + r_s) and use their
cell's section with that plane (:func:`ground_section`). Their Σ has no z term, so the
planes between robots of such a fleet come from ``σ² I`` and only the buffers from Σ
(:func:`separator_covariances`); their liveness roadmap runs around the footprints of the
boxes that reach their plane (:func:`ground_footprints`).

The authors' main setup — one 2-D team of single integrators under the one-step
controller — is the same loop with one team whose rows are views of the fleet's cells
(no per-step copies), which keeps the 50,000-robot step of
``benchmarks/avoidance_scale.py`` as fast as a dedicated loop.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from shapely.geometry import Polygon

from ..core.family import expect_spec
from ..core.geometry import box_vertices
from ..core.recorder import Recorder
from ..core.rng import as_generator, resolve_seed
from ..core.trace import Trace, to_plain
from ..dynamics import double_integrator as di
from ..dynamics import quadrotor as quad
from ..dynamics import single_integrator
from ..dynamics import unicycle as uni
from .braking import braking_control, braking_rule, stopping_point
from .buffer import buffer, confidence_quantile, shadow_epsilon
from .cell import CellGeometry, Cells, Kind, build_cells
from .cell3d import (
    box_shadow_planes,
    project_onto_polytope,
    shadow_radius,
    workspace_box_planes,
)
from .controller import (
    ControllerState,
    DeadlockParams,
    cell_rows,
    single_integrator_control,
)
from .detour import Detours
from .diff_drive import three_projection_control
from .liveness import LivenessParams, ParkingState, steering_goals
from .metrics import ControllerCounts, RunTally
from .mpc import BuavcMPC, GoalRotation, SingleIntegratorParams
from .navigation import Navigation, Roadmap
from .obstacles import ObstacleSet, wall_planes
from .orca import orca_velocities, preferred_velocities
from .orca_obstacles import ObstacleEdges
from .projection import project_onto_cells
from .segment_cells import with_braking_segments
from .spec import Space3DSpec, Spec, TeamSpec, initial_layout

RECORD_CELLS_MAX_ROBOTS = 64
"""Cells are recorded by default for fleets up to this size (``record_cells`` overrides)."""
MPC_NO_MPC, MPC_SOLVED, MPC_FALLBACK, MPC_ARRIVED = -1, 0, 1, 2  # mpc_status codes (int8)
CONTROL_WIDTH = {"single_integrator": 2, "double_integrator": 2, "unicycle": 2, "quadrotor": 4}
"""Inputs per model; the ``controls`` array is as wide as the widest team's (zero-padded)."""


# ---------------------------------------------------------------------------------------
# what a method's cells are made of
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MethodSetup:
    """What the cells of a method are built from (see the module docstring).

    Attributes
    ----------
    method: ``buavc``, ``bvc``, ``bvc_inflated`` or ``orca``.
    quantile: ``Φ⁻¹(√(1 − δ))`` of the chance buffer β (0 without chance constraint).
    epsilon: ε of the obstacles' ε-shadow, ``1 − √(1 − δ)`` (appendix A).
    inflation_sigmas: k of the inflated radius ``r_s + k σ_max`` (0 unless ``bvc_inflated``).
    """

    method: str
    quantile: float
    epsilon: float
    inflation_sigmas: float

    @property
    def chance_constrained(self) -> bool:
        """Whether the cells carry the chance constraint (Σ, Σ_o and δ enter them)."""
        return self.method == "buavc"

    def cell_covariance(self, cov: np.ndarray) -> np.ndarray:
        """The Σ a cell uses: the estimate's covariance for B-UAVC, zero for the BVC variants."""
        return cov if self.chance_constrained else np.zeros_like(cov)

    def cell_radius(self, radius: float, sigma: float) -> float:
        """The safety radius a cell uses: ``r_s``, or ``r_s + k σ_max`` for the inflated BVC."""
        return radius + self.inflation_sigmas * sigma


def method_setup(method: str, delta: float, inflation_sigmas: float) -> MethodSetup:
    """The cell ingredients of ``method`` at threshold ``delta`` (Sec. 4 and appendix A)."""
    if method == "buavc":
        return MethodSetup(method, confidence_quantile(delta), shadow_epsilon(delta), 0.0)
    return MethodSetup(method, 0.0, shadow_epsilon(delta), inflation_sigmas if method == "bvc_inflated" else 0.0)


def obstacle_set(polygons: list[np.ndarray], obstacle_cov: np.ndarray, setup: MethodSetup) -> ObstacleSet:
    """The 2-D obstacles a method's cells see: with their ε-shadows under Σ_o (appendix A,
    Lemma 1 and Theorem 1) for B-UAVC, nominal otherwise."""
    if setup.chance_constrained:
        return ObstacleSet.build(polygons, np.repeat(obstacle_cov[None], len(polygons), 0), setup.epsilon)
    return ObstacleSet.build(polygons, np.zeros((len(polygons), 2, 2)), 0.0)


def obstacle_clearance(radius: float, sigma: float, quantile: float, obstacles: ObstacleSet, obstacle_cov: np.ndarray) -> float:
    """Largest distance a cell keeps a robot from a nominal obstacle boundary: r_s + the
    chance buffer ``Φ⁻¹(√(1 − δ)) σ`` + the ε-shadow ``r_ε σ_o`` (used to place the detour
    vertices of appendix C)."""
    shadow = float(obstacles.shadow_radius.max(initial=0.0)) * float(np.sqrt(np.linalg.eigvalsh(obstacle_cov).max()))
    return radius + quantile * sigma + (shadow if np.isfinite(shadow) else 0.0)


def grown_obstacle_vertices(polygons: list[np.ndarray], margin: float) -> np.ndarray | None:
    """Vertices ``(O, V, 2)`` of the obstacles grown by ``margin`` (mitred, padded by
    repetition), the detour targets of the obstacle branch of appendix C."""
    grown = [Polygon(p).buffer(margin, join_style="mitre") for p in polygons]
    if not grown:
        return None
    verts = [np.asarray(p.exterior.coords)[:-1] for p in grown]
    v_max = max(len(v) for v in verts)
    return np.stack([np.vstack([v, np.repeat(v[-1:], v_max - len(v), 0)]) for v in verts])


def noise_factor(cov: np.ndarray) -> np.ndarray:
    """``L`` with ``L Lᵀ = Σ`` for any symmetric PSD ``Σ`` (Cholesky, eigen-factor if singular)."""
    if not np.any(cov):
        return np.zeros_like(cov)
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(cov)
        return v * np.sqrt(np.maximum(w, 0.0))


def team_noise_factor(team: TeamSpec, dim: int) -> np.ndarray:
    """``L`` with ``L Lᵀ`` = :func:`team_covariance` (3-D: ``σ diag(1, 1, 1 or 0)`` exactly)."""
    if dim == 2:
        cov = team.covariance()
        return noise_factor(cov) if cov.ndim == 2 else np.stack([noise_factor(c) for c in cov])
    return team.sigma * np.diag([1.0, 1.0, 1.0 if team.flying else 0.0])


def team_covariance(team: TeamSpec, dim: int) -> np.ndarray:
    """The ``(dim, dim)`` covariance of a team's position estimates: Σ in 2-D (``(n, 2, 2)``
    when its robots have their own); in 3-D
    ``σ² I`` for quadrotors and ``σ² diag(1, 1, 0)`` for ground robots (no z noise)."""
    if dim == 2:
        return team.covariance()
    return team.sigma**2 * np.diag([1.0, 1.0, 1.0 if team.flying else 0.0])


# ---------------------------------------------------------------------------------------
# the cells of the whole fleet
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BoxObstacles:
    """3-D box obstacles (yawed about z) with uncertain position ``N(0, cov)`` and the ε of their shadows."""

    centers: np.ndarray
    sizes: np.ndarray
    yaws: np.ndarray
    cov: np.ndarray
    epsilon: float

    @property
    def count(self) -> int:
        return len(self.centers)


@dataclass(frozen=True)
class CellModel:
    """What every robot's B-UAVC is built from (Sec. 4): each estimate's covariance Σ_i
    and safety radius, the buffer quantile, the walls and the obstacles with their
    shadows (2-D polygons in ``geometry``, 3-D boxes in ``boxes``), the local box R_loc.

    ``separator_covs`` (3-D teams with ground robots, :func:`separator_covariances`) are the
    covariances the pairwise separating planes are computed from when they differ from Σ_i;
    the buffers β always use Σ_i."""

    covs: np.ndarray
    radius: np.ndarray
    quantile: float
    geometry: CellGeometry
    local_box: float
    boxes: BoxObstacles | None = None
    separator_covs: np.ndarray | None = None

    def cells(self, estimates: np.ndarray, obstacle_shift: np.ndarray, stops: np.ndarray | None = None) -> Cells:
        """The cells of all robots from their estimates ``(N, d)`` and the obstacles'
        estimated displacements ``(O, d)``; with ``stops`` ``(N, d)``, the braking rule's
        stopping points, the rows of every robot whose stop differs from its estimate are
        built from the braking segments ``[p̂_i, stop_i]`` (:mod:`.segment_cells`)."""
        if self.boxes is None:
            geometry = replace(self.geometry, obstacles=shifted(self.geometry.obstacles, obstacle_shift))
            cells = build_cells(estimates, self.covs, self.radius, self.quantile, geometry, self.local_box)
            if stops is None:
                return cells
            return with_braking_segments(cells, estimates, stops, self.covs, self.radius, self.quantile, obstacles=geometry.obstacles)
        if self.separator_covs is None:
            cells = build_cells(estimates, self.covs, self.radius, self.quantile, self.geometry, self.local_box)
        else:
            cells = self.rebuffered(build_cells(estimates, self.separator_covs, self.radius, self.quantile, self.geometry, self.local_box))
        cells = cells if self.boxes.count == 0 else self.with_box_rows(cells, estimates, obstacle_shift)
        if stops is None:
            return cells
        b, sigma_o = self.boxes, float(np.sqrt(self.boxes.cov[0, 0]))  # Σ_o = σ_o² I in every 3-D scenario
        return with_braking_segments(cells, estimates, stops, self.covs, self.radius, self.quantile,
                                     boxes=(b.centers + obstacle_shift, b.sizes, b.yaws, sigma_o, b.epsilon))

    def rebuffered(self, cells: Cells) -> Cells:
        """``cells`` built with ``separator_covs``, their buffers replaced by those of Σ_i:
        ``b + q (√(aᵀ Σ_sep a) − √(aᵀ Σ_i a))`` (the planes stay, so the pair's two rows stay reciprocal)."""
        b = cells.b + buffer(cells.A, self.separator_covs[:, None], 0.0, self.quantile) - buffer(cells.A, self.covs[:, None], 0.0, self.quantile)
        return replace(cells, b=np.where(cells.valid, b, cells.b))

    def with_box_rows(self, cells: Cells, estimates: np.ndarray, shift: np.ndarray) -> Cells:
        """``cells`` plus one row per box inside each robot's local box: the max-margin plane
        to the box's ε-shadow (appendix A), tightened by the robot's buffer β."""
        boxes = self.boxes
        centers = boxes.centers + shift
        a, b = box_shadow_planes(estimates, centers, boxes.sizes, boxes.yaws, boxes.cov, boxes.epsilon)
        b = b - buffer(a, self.covs[:, None], self.radius[:, None], self.quantile)
        reach = 0.5 * np.linalg.norm(boxes.sizes, axis=1)
        near = np.all(np.abs(estimates[:, None] - centers[None]) <= self.local_box + reach[None, :, None], axis=-1)
        return Cells(np.concatenate([cells.A, a], 1), np.concatenate([cells.b, np.where(near, b, 1.0)], 1),
                     np.concatenate([cells.valid, near], 1),
                     np.concatenate([cells.kind, np.full(near.shape, int(Kind.OBSTACLE), np.int8)], 1),
                     np.concatenate([cells.source, np.broadcast_to(np.arange(boxes.count), near.shape)], 1))


def shifted(obstacles: ObstacleSet, shift: np.ndarray) -> ObstacleSet:
    """The obstacle set displaced by ``shift`` ``(O, d)`` (the obstacles' position estimates)."""
    if obstacles.count == 0:
        return obstacles
    return replace(obstacles, vertices=obstacles.vertices + shift[:, None], lo=obstacles.lo + shift, hi=obstacles.hi + shift)


def cell_model(spec: Spec, setup: MethodSetup) -> CellModel:
    """The :class:`CellModel` of a scenario under a method (one team: a broadcast Σ, so
    the separators take the shared-covariance closed form)."""
    teams, slices, dim = spec.team_specs(), spec.team_slices(), spec.dim
    n = slices[-1].stop
    if len(teams) == 1:  # one team: a broadcast Σ unless the robots have their own
        covs = np.broadcast_to(setup.cell_covariance(team_covariance(teams[0], dim)), (n, dim, dim))
    else:
        covs = np.empty((n, dim, dim))
        for team, sl in zip(teams, slices):
            covs[sl] = setup.cell_covariance(team_covariance(team, dim))
    radius = np.empty(n)
    for team, sl in zip(teams, slices):
        radius[sl] = setup.cell_radius(spec.robots.radius, team.largest_sigma())
    if spec.space3d is None:
        ws = spec.workspace
        geometry = CellGeometry(obstacle_set(ws.obstacle_polygons(), ws.obstacle_covariance(), setup), *wall_planes(ws.bounds_vertices()))
        return CellModel(covs, radius, setup.quantile, geometry, spec.local_box)
    space = spec.space3d
    no_polygons = ObstacleSet(np.zeros((0, 1, 3)), np.zeros((0, 3, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    geometry = CellGeometry(no_polygons, *workspace_box_planes(space.lower, space.upper))
    box_cov = setup.cell_covariance(space.obstacle_sigma**2 * np.eye(3))
    boxes = BoxObstacles(*space.box_arrays(), box_cov, setup.epsilon)
    return CellModel(covs, radius, setup.quantile, geometry, spec.local_box, boxes, separator_covariances(spec, setup, covs))


def separator_covariances(spec: Spec, setup: MethodSetup, covs: np.ndarray) -> np.ndarray | None:
    """The covariances the separating planes of a 3-D fleet with ground robots are computed
    from: ``σ² I`` for every robot (``None`` when every robot flies: Σ_i itself).

    A ground robot's Σ_i = σ² diag(1, 1, 0) is singular: its z is known exactly. Appendix B's
    minimax separator against a flying robot then tends to the horizontal plane through the
    ground robot's estimate (a horizontal normal misclassifies it with probability 0 at any
    offset), which leaves its section empty after the buffer r_s, however high the flying
    robot is. Any plane that both robots compute alike keeps the chance constraint (the
    argument of docs/theory/buavc.md "Buffer" holds for every plane once β uses the true Σ_i), so
    the plane is taken from ``σ² I`` — for equal σ the perpendicular bisector, the ordinary
    Voronoi face, which gives each robot half the distance — and β from Σ_i
    (:meth:`CellModel.rebuffered`)."""
    teams = spec.team_specs()
    if all(team.flying for team in teams):
        return None
    out = np.empty_like(covs)
    for team, sl in zip(teams, spec.team_slices()):
        out[sl] = setup.cell_covariance(team.sigma**2 * np.eye(3))
    return out


def ground_footprints(space: Space3DSpec, z: float, radius: float) -> list[np.ndarray]:
    """Footprints ``(4, 2)`` of the boxes of a 3-D space that a ground robot (a sphere of
    ``radius`` centred at height ``z``) can touch: the 2-D obstacles of ground teams."""
    centers, sizes, yaws = space.box_arrays()
    reach = np.abs(centers[:, 2] - z) < 0.5 * sizes[:, 2] + radius
    return [box_vertices(c, s, y) for c, s, y, r in zip(centers, sizes, yaws, reach) if r]


def ground_section(cells: Cells, z: float) -> Cells:
    """The section of 3-D cells with the plane ``z`` (ground robots), as 2-D cells:
    ``{(x, y) : a_xy·(x, y) ≤ b − a_z z}`` with rows normalised; rows with ``a_xy ≈ 0``
    are dropped when satisfied and make the cell empty otherwise, except the floor and
    ceiling walls, which do not bound ground robots."""
    a_xy = cells.A[..., :2]
    norm = np.linalg.norm(a_xy, axis=-1)
    b = cells.b - cells.A[..., 2] * z
    flat = norm < 1e-9
    keep = cells.valid & ~(flat & ((b >= 0) | (cells.kind == int(Kind.WALL))))
    A = np.where(flat[..., None], 0.0, a_xy / np.where(flat, 1.0, norm)[..., None])
    b = np.where(flat, np.where(b >= 0, 1.0, b), b / np.where(flat, 1.0, norm))
    return Cells(A, np.where(keep, b, 1.0), keep, cells.kind, cells.source)


def empty_cells(cells: Cells, points: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Which cells are empty: none that holds its robot's ``points`` (``inside``); the
    others by an exact projection onto the cell (2-D, :func:`project_onto_cells`; 3-D,
    :func:`~.cell3d.project_onto_polytope`), which reports infeasibility."""
    empty = np.zeros(len(points), bool)
    out = np.flatnonzero(~inside)
    if len(out) == 0:
        return empty
    A, b, valid = cells.A[out], cells.b[out], cells.valid[out]
    if points.shape[1] == 2:
        empty[out] = project_onto_cells(points[out], Cells(A, b, valid, cells.kind[out], cells.source[out])).empty
    else:
        empty[out] = ~project_onto_polytope(points[out], A, b, valid)[1]
    return empty


def project_2d(points: np.ndarray, A: np.ndarray, b: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact projection onto 2-D cells in the ``(points, A, b, valid) -> (proj, ok)`` form
    :func:`~.diff_drive.three_projection_control` takes."""
    proj = project_onto_cells(points, Cells(A, b, valid, np.zeros(valid.shape, np.int8), np.zeros(valid.shape, np.intp)))
    return np.where(proj.empty[:, None], points, proj.point), ~proj.empty


# ---------------------------------------------------------------------------------------
# teams at run time
# ---------------------------------------------------------------------------------------
@dataclass
class Group:
    """One team at run time: its slice of the fleet, TRUE states, controller and memory."""

    name: str
    kind: str
    controller: str
    index: slice
    params: object
    v_max: float
    flying: bool
    state: np.ndarray
    arrived: np.ndarray
    z: float | None = None  # plane of ground robots in 3-D
    si_state: ControllerState | None = None
    rotation: GoalRotation | None = None
    mpc: BuavcMPC | None = None
    grown: np.ndarray | None = field(default=None, repr=False)
    navigation: Navigation | None = field(default=None, repr=False)
    parking: ParkingState | None = field(default=None, repr=False)
    sigma: float = 0.0  # largest σ of the team's estimates that the cells account for

    @property
    def plane_dim(self) -> int:
        """Dimension of the space the team's controller works in."""
        return 3 if self.flying else 2

    def positions(self, dim: int) -> np.ndarray:
        """True positions ``(n, dim)``."""
        p = self.state[:, : self.plane_dim]
        if dim == 3 and not self.flying:
            p = np.column_stack([p, np.full(len(p), self.z)])
        return p

    def headings(self) -> np.ndarray | None:
        """Headings ``(n,)`` (unicycle θ, quadrotor yaw ψ), ``None`` for single/double integrators."""
        return self.state[:, 2] if self.kind == "unicycle" else self.state[:, 8] if self.kind == "quadrotor" else None

    def has_arrived(self) -> np.ndarray:
        """Latched arrival flags (a robot arrives when its estimate is within the tolerance)."""
        return self.arrived if self.si_state is None else self.si_state.arrived

    def deadlock_counts(self) -> np.ndarray:
        """Deadlock detections per robot so far (appendix C)."""
        for memory in (self.si_state, self.mpc, self.rotation):
            if memory is not None:
                return memory.deadlocks
        return np.zeros(len(self.arrived), np.int64)

    def advance(self, u: np.ndarray, dt: float) -> None:
        """Move the TRUE states one step under the inputs ``u`` (the team's dynamics)."""
        if self.kind == "single_integrator":
            self.state = single_integrator.step(self.state, u[:, :2], dt)
        elif self.kind == "double_integrator":
            self.state = di.step(self.state, u[:, :2], dt, self.params)
        elif self.kind == "unicycle":
            self.state = uni.step(self.state, u[:, :2], dt, self.params)
        else:
            self.state = quad.step(self.state, u, dt, self.params)


def make_group(spec: Spec, team: TeamSpec, index: slice, starts: np.ndarray, goals: np.ndarray, grown: np.ndarray | None) -> Group:
    """A team's initial state (at rest; unicycles facing their goal) and controller."""
    n, kind, model = team.n, team.model.kind, team.model
    xy = starts[:, :2]
    if kind == "single_integrator":
        params, state = SingleIntegratorParams(v_max=team.v_max), xy.copy()
    elif kind == "double_integrator":
        params, state = di.DoubleIntegratorParams(a_max=model.a_max, v_max=team.v_max), np.column_stack([xy, np.zeros((n, 2))])
    elif kind == "unicycle":
        heading = np.arctan2(goals[:, 1] - xy[:, 1], goals[:, 0] - xy[:, 0])
        params, state = uni.UnicycleParams(v_max=team.v_max, omega_max=model.omega_max), np.column_stack([xy, heading])
    else:
        params, state = model.quadrotor, np.column_stack([starts[:, :3], np.zeros((n, 6))])
    group = Group(team.name, kind, model.controller, index, params, team.v_max, team.flying, state, np.zeros(n, bool), grown=grown)
    if spec.space3d is not None and not team.flying:
        group.z = spec.ground_height()
    d = spec.deadlock
    if spec.method == "orca":
        pass  # ORCA keeps only the arrival flags
    elif model.controller == "mpc":
        group.mpc = BuavcMPC(kind, params, dim=group.plane_dim, dt=spec.dt, config=model.mpc, n_robots=n,
                             speed_limit=team.v_max if kind == "quadrotor" else None, position_sigma=team.largest_sigma())
    elif kind == "single_integrator":
        group.si_state = ControllerState.initial(n, d.window)
    else:
        group.rotation = GoalRotation(n, d.window, d.progress_fraction * team.v_max * d.window * spec.dt, d.recover_steps)
    return group


@dataclass(frozen=True)
class StepFlags:
    """Robots newly detected in deadlock and robots (not arrived) whose cell was empty, this
    step; and, for every robot, whether its estimate lay in its own cell when the cell was
    built (the premise of the chance constraint, Sec. 4; ``None`` until
    :meth:`World.measure_premise`) and whether the cell was empty (``reported``: whether the
    controller found that out itself)."""

    deadlocked: np.ndarray
    empty: np.ndarray
    estimate_in_cell: np.ndarray | None
    cell_empty: np.ndarray
    reported: np.ndarray


# ---------------------------------------------------------------------------------------
# the world
# ---------------------------------------------------------------------------------------
class World:
    """Everything the loop needs, built once from the spec: starts and goals, the noise,
    the fleet's cells, the teams with their controllers and dynamics.

    Parameters
    ----------
    spec : ~robofleet.avoidance.spec.Spec
        The scenario.
    rng:
        The run's generator; random layouts are drawn from it here, the noise later.
    """

    def __init__(self, spec: Spec, rng: np.random.Generator):
        self.spec, self.dim, self.dt = spec, spec.dim, spec.dt
        self.setup = method_setup(spec.method, spec.delta, spec.inflation_sigmas)
        self.starts, self.goals, slices = initial_layout(spec, rng)
        self.n = len(self.starts)
        teams = spec.team_specs()
        self.cell_model = None if spec.method == "orca" else cell_model(spec, self.setup)
        self.orca_obstacles = ObstacleEdges.from_workspace(spec.workspace.build()) if spec.method == "orca" else None
        self.liveness = LivenessParams(**spec.liveness.model_dump())
        self.groups = [make_group(spec, team, sl, self.starts[sl], self.goals[sl], self.detour_vertices(team))
                       for team, sl in zip(teams, slices)]
        for team, sl, g in zip(teams, slices, self.groups):
            g.navigation = self.navigation(team, self.goals[sl])
            g.sigma = self.team_sigma(team)
            if g.si_state is None:  # single integrators keep theirs in the controller state
                g.parking = ParkingState.initial(team.n)
        self.noise_factor = self.position_noise_factor(teams, slices)
        self.obstacle_factor, self.n_obstacles = self.obstacle_noise()
        self.radius = np.full(self.n, spec.robots.radius)
        self.v_max = np.concatenate([np.full(t.n, t.v_max) for t in teams])
        self.control_width = max(CONTROL_WIDTH[t.model.kind] for t in teams)
        self.velocity = np.zeros((self.n, self.dim))
        self.deadlock = DeadlockParams(**spec.deadlock.model_dump())
        self.fallback_steps = 0
        self.solve_steps = 0
        self.has_mpc = any(t.model.controller == "mpc" for t in teams)
        self.mpc_status = np.full(self.n, MPC_NO_MPC, np.int8)

    # -- set-up ---------------------------------------------------------------------------
    def obstacle_clearance(self, team: TeamSpec) -> float | None:
        """The whole clearance a 2-D or ground team's cells keep from the nominal obstacles
        (r_s, the chance buffer, the ε-shadow); ``None`` without cells or for flying teams.
        In 3-D the ε-shadow of a box is ``√(χ²₃⁻¹(1 − ε)) σ_o`` (appendix A, Lemma 1)."""
        if self.cell_model is None or (self.dim == 3 and team.flying):
            return None
        sigma = self.team_sigma(team)
        radius = self.setup.cell_radius(self.spec.robots.radius, team.largest_sigma())
        if self.dim == 3:
            sigma_o = self.spec.space3d.obstacle_sigma if self.setup.chance_constrained else 0.0
            return radius + self.setup.quantile * sigma + shadow_radius(self.setup.epsilon, 3) * sigma_o
        return obstacle_clearance(radius, sigma, self.setup.quantile, self.cell_model.geometry.obstacles, self.spec.workspace.obstacle_covariance())

    def plane_obstacles(self) -> tuple[list[np.ndarray], tuple[float, float, float, float]]:
        """The obstacle polygons 2-D and ground teams drive around and the workspace's
        ``(x_min, y_min, x_max, y_max)``: in 3-D the footprints of the boxes that reach the
        ground robots' plane (:func:`ground_footprints`)."""
        if self.spec.space3d is None:
            corners = self.spec.workspace.bounds_vertices()
            return self.spec.workspace.obstacle_polygons(), (*corners.min(axis=0), *corners.max(axis=0))
        space = self.spec.space3d
        bounds = (space.lower[0], space.lower[1], space.upper[0], space.upper[1])
        return ground_footprints(space, self.spec.ground_height(), self.spec.robots.radius), bounds

    def detour_vertices(self, team: TeamSpec) -> np.ndarray | None:
        """Appendix C detour targets of a 2-D single-integrator team: the obstacles grown
        by 1.05 × the whole clearance its cells keep (r_s, the chance buffer, the ε-shadow)."""
        clearance = self.obstacle_clearance(team)
        if clearance is None or team.model.kind != "single_integrator" or team.model.controller != "one_step":
            return None
        return grown_obstacle_vertices(self.plane_obstacles()[0], 1.05 * clearance)

    def navigation(self, team: TeamSpec, goals: np.ndarray) -> Navigation | None:
        """The roadmap sub-goals of a 2-D or ground team (:mod:`.navigation`) when liveness
        asks for them and there are obstacles: nodes at 1.15 × the team's obstacle clearance;
        gaps narrower than 1.8 × (that clearance + ``passage_sigmas`` of its largest σ)
        closed, the gaps a robot can enter but not pass (measured, one robot through a gap
        between two boxes at the random scenarios' σ = 0.1 m and clearance 0.61 m, seeds
        0–9: 0/10 at 1.2 m wide without the margin; with it the roadmap goes round, 10/10)."""
        clearance = self.obstacle_clearance(team)
        polygons, bounds = self.plane_obstacles()
        if clearance is None or not polygons or not (self.liveness.enabled and self.liveness.roadmap):
            return None
        passage = self.liveness.passage_sigmas * self.team_sigma(team)
        roadmap = Roadmap(polygons, 1.15 * clearance, bounds, clearance, passage)
        return Navigation(roadmap, goals[:, :2], self.detours(team, roadmap, goals[:, :2]))

    def team_sigma(self, team: TeamSpec) -> float:
        """The largest standard deviation of a team's position estimate the cells account
        for (0 for the deterministic methods)."""
        return team.largest_sigma() if self.setup.chance_constrained else 0.0

    def detours(self, team: TeamSpec, roadmap: Roadmap, goals: np.ndarray) -> Detours | None:
        """The detour rule of :mod:`.detour` (when liveness asks for it), its discs the
        pair clearance ``2 β`` the cells keep between two estimates (r_s + the chance buffer,
        twice). Not for unicycles, as the right-hand rule: on the mixed ground/air team
        (differential-drive ground robots) detours lowered success at σ × 0.5 from 20/20
        to 16/20 (``benchmarks/mpc_3d.py``, seeds 0–19), without changing σ × 1 or × 2."""
        if not self.liveness.detour or team.model.kind == "unicycle":
            return None
        sigma = self.team_sigma(team)
        pair = 2.0 * (self.setup.cell_radius(self.spec.robots.radius, sigma) + self.setup.quantile * sigma)
        return Detours(roadmap, goals, pair, self.spec.local_box, self.liveness)

    def position_noise_factor(self, teams: tuple[TeamSpec, ...], slices: list[slice]) -> np.ndarray:
        """``L`` with ``L Lᵀ = Σ``: one ``(d, d)`` factor for one team, else ``(N, d, d)``."""
        if len(teams) == 1:  # (d, d) shared, or (N, d, d) per robot
            return team_noise_factor(teams[0], self.dim)
        factors = np.empty((self.n, self.dim, self.dim))
        for team, sl in zip(teams, slices):
            factors[sl] = team_noise_factor(team, self.dim)
        return factors

    def obstacle_noise(self) -> tuple[np.ndarray, int]:
        """The factor of Σ_o and the number of obstacles whose position estimates are noisy."""
        if self.spec.space3d is None:
            ws = self.spec.workspace
            return noise_factor(ws.obstacle_covariance()), len(ws.obstacles)
        space = self.spec.space3d
        return space.obstacle_sigma * np.eye(3), len(space.boxes)

    # -- sensing --------------------------------------------------------------------------
    def position_noise(self, rng: np.random.Generator) -> np.ndarray:
        """Estimation errors ``(N, d)``, one draw from ``N(0, Σ_i)`` per robot."""
        z = rng.standard_normal((self.n, self.dim))
        return z @ self.noise_factor.T if self.noise_factor.ndim == 2 else np.einsum("nij,nj->ni", self.noise_factor, z)

    def obstacle_shift(self, rng: np.random.Generator) -> np.ndarray:
        """Estimation errors ``(O, d)`` of the obstacles' positions, drawn from ``N(0, Σ_o)``."""
        return rng.standard_normal((self.n_obstacles, self.dim)) @ self.obstacle_factor.T

    def positions(self) -> np.ndarray:
        """True positions ``(N, d)``."""
        if len(self.groups) == 1:
            return self.groups[0].positions(self.dim)
        out = np.empty((self.n, self.dim))
        for g in self.groups:
            out[g.index] = g.positions(self.dim)
        return out

    @property
    def has_headings(self) -> bool:
        return any(g.headings() is not None for g in self.groups)

    def headings(self) -> np.ndarray:
        """Headings ``(N,)``, NaN for robots without one."""
        out = np.full(self.n, np.nan)
        for g in self.groups:
            heading = g.headings()
            if heading is not None:
                out[g.index] = heading
        return out

    def arrived(self) -> np.ndarray:
        """Latched arrival flags ``(N,)``."""
        if len(self.groups) == 1:
            return self.groups[0].has_arrived()
        return np.concatenate([g.has_arrived() for g in self.groups])

    def deadlock_counts(self) -> np.ndarray:
        """Deadlock detections per robot so far."""
        return np.concatenate([g.deadlock_counts() for g in self.groups])

    # -- deciding ---------------------------------------------------------------------------
    def decide(self, estimates: np.ndarray, obstacle_shift: np.ndarray) -> tuple[Cells | None, np.ndarray, StepFlags]:
        """Every robot's cell and input for this step: ``(cells, controls (N, width), flags)``."""
        before = self.deadlock_counts().copy()
        empty, reported = np.zeros(self.n, bool), np.ones(self.n, bool)
        if self.cell_model is None:
            cells, u = None, self.orca_control(estimates)
        else:
            cells = self.cell_model.cells(estimates, obstacle_shift, self.braking_stops(estimates))
            u = np.zeros((self.n, self.control_width))
            for g in self.groups:
                control, team_empty = self.team_control(g, estimates, self.team_cells(cells, g))
                if team_empty is None:
                    reported[g.index] = False
                else:
                    empty[g.index] = team_empty
                u[g.index, : control.shape[1]] = control
        return cells, u, StepFlags(self.deadlock_counts() > before, empty & ~self.arrived(), None, empty, reported)

    def braking_stops(self, estimates: np.ndarray) -> np.ndarray | None:
        """Where each robot would come to rest under the braking rule's brake (:mod:`.braking`):
        ``stop(p̂_i, v_i)`` for the double integrators it drives, the estimate for every other
        robot; ``None`` without such a team (the cells then separate the estimates alone)."""
        braking = [g for g in self.groups if g.kind == "double_integrator" and g.mpc is None]
        if not braking:
            return None
        stops = estimates.copy()
        for g in braking:
            stops[g.index, :2] = stopping_point(estimates[g.index, :2], g.state[:, 2:], g.params.a_max, self.dt)
        return stops

    def measure_premise(self, cells: Cells | None, estimates: np.ndarray, flags: StepFlags) -> StepFlags:
        """``flags`` completed with whether each estimate lay in its own cell (the premise of
        the chance constraint) and, where the controller did not report it, whether the
        cell was empty (:func:`empty_cells`). Instrumentation, kept out of the timed step;
        all False for ORCA, which builds no cells."""
        inside, empty = np.zeros(self.n, bool), flags.cell_empty.copy()
        if cells is None:
            return replace(flags, estimate_in_cell=inside)
        for g in self.groups:
            rows, p_est = self.team_cells(cells, g), estimates[g.index, : g.plane_dim]
            inside[g.index] = rows.contains(p_est)
            unknown = ~flags.reported[g.index]
            if unknown.any():
                empty[g.index] = np.where(unknown, empty_cells(rows, p_est, inside[g.index]), empty[g.index])
        return StepFlags(flags.deadlocked, empty & ~self.arrived(), inside, empty, flags.reported)

    def team_cells(self, cells: Cells, g: Group) -> Cells:
        """A team's cells (their section with the ground plane for ground robots in 3-D)."""
        rows = cell_rows(cells, g.index)
        return ground_section(rows, g.z) if (self.dim == 3 and not g.flying) else rows

    def team_control(self, g: Group, estimates: np.ndarray, cells: Cells) -> tuple[np.ndarray, np.ndarray | None]:
        """Inputs of one team and its robots whose cell was empty (``None`` when the
        controller does not find out; :func:`empty_cells` then decides)."""
        spec, dt = self.spec, self.dt
        p_est = estimates[g.index, : g.plane_dim]
        goal = self.goals[g.index, : g.plane_dim]
        if g.si_state is not None:
            u, info = single_integrator_control(p_est, goal, cells, g.si_state, v_max=g.v_max, dt=dt, goal_tolerance=spec.goal_tolerance,
                                                deadlock=self.deadlock, grown_obstacles=g.grown,
                                                liveness=self.liveness, local_box=spec.local_box, navigation=g.navigation,
                                                sigma=g.sigma)
            return u, info["empty"]
        g.arrived |= np.linalg.norm(goal - p_est, axis=1) <= spec.goal_tolerance
        state_est = g.state.copy()
        state_est[:, : g.plane_dim] = p_est
        if g.mpc is not None:
            u, info = g.mpc.control(state_est, goal, cells.A, cells.b, cells.valid, arrived=g.arrived)
            self.fallback_steps += int(info["fallback"].sum())
            self.solve_steps += int((~g.arrived).sum())
            self.mpc_status[g.index] = np.where(g.arrived, MPC_ARRIVED, np.where(info["fallback"], MPC_FALLBACK, MPC_SOLVED))
            return u, None
        moving = np.zeros(len(goal), bool)
        if self.liveness.enabled:
            # a blocked double integrator or unicycle comes to rest, so holding still does
            # not tell a parked neighbour from a blocked one; unicycles do not turn right
            rules = replace(self.liveness, still_radius=0.0, right_hand_angle=self.liveness.right_hand_angle if g.kind != "unicycle" else 0.0)
            goal, moving = steering_goals(p_est, goal, g.arrived, cells, rules, g.parking, spec.local_box, g.navigation,
                                          spec.goal_tolerance)
        working = g.rotation.working_goals(p_est, goal, g.arrived)
        holding = g.arrived & ~moving
        if g.kind == "double_integrator":
            proj = project_onto_cells(working, cells)
            target = np.where(proj.empty[:, None], p_est, proj.point)
            u, _ = braking_rule(p_est, g.state[:, 2:], target, cells.A, cells.b, cells.valid, g.params, dt)
            return np.where(holding[:, None], braking_control(g.state[:, 2:], g.params.a_max, dt), u), proj.empty
        u = three_projection_control(state_est, working, cells.A, cells.b, cells.valid, g.params, dt, project=project_2d)
        return np.where(holding[:, None], 0.0, u), None

    def orca_control(self, estimates: np.ndarray) -> np.ndarray:
        """ORCA velocities (van den Berg et al. 2011) for all robots, preferring the goal at
        full speed, avoiding the nominal obstacles and the walls; arrived robots prefer to
        stand still."""
        for g in self.groups:
            g.arrived |= np.linalg.norm(self.goals[g.index] - estimates[g.index], axis=1) <= self.spec.goal_tolerance
        arrived = self.arrived()
        pref = np.where(arrived[:, None], 0.0, preferred_velocities(estimates, self.goals, self.v_max, self.dt))
        v, _ = orca_velocities(estimates, self.velocity, pref, self.radius, self.v_max, self.spec.orca, self.dt, self.orca_obstacles)
        return v

    # -- moving ---------------------------------------------------------------------------
    def advance(self, u: np.ndarray) -> None:
        """Move every TRUE state one step (ORCA also needs the realised velocities)."""
        before = self.positions() if self.cell_model is None else None
        for g in self.groups:
            g.advance(u[g.index], self.dt)
        if before is not None:
            self.velocity = (self.positions() - before) / self.dt

    def settled(self, estimates: np.ndarray) -> bool:
        """No arrived robot is away from its goal on a yield (:mod:`.liveness`)."""
        tol = self.spec.goal_tolerance
        for g in self.groups:
            parking = g.si_state.parking if g.si_state is not None else g.parking
            if parking is not None and not parking.settled(estimates[g.index, :2], self.goals[g.index, :2], tol):
                return False
        return True

    def counts(self) -> ControllerCounts:
        """The controllers' counters (deadlocks, MPC fallbacks; empty cells are counted from events)."""
        livelocks = sum(int(g.si_state.livelocks.sum()) for g in self.groups if g.si_state is not None)
        return ControllerCounts(deadlock_detections=int(self.deadlock_counts().sum()), livelock_detections=livelocks,
                                mpc_fallback_steps=self.fallback_steps, mpc_solve_steps=self.solve_steps)

    def metadata(self) -> dict:
        """What is needed to interpret the arrays (viz, metrics, replays), as plain JSON values."""
        spec, teams = self.spec, self.spec.team_specs()
        covs = [team_covariance(t, self.dim) for t in teams]
        per_robot = lambda values: [v for t, v in zip(teams, values) for _ in range(t.n)]  # noqa: E731
        shared = self.dim == 2 and covs[0].ndim == 2 and all(np.array_equal(c, covs[0]) for c in covs)
        return to_plain({
            "method": spec.method, "dt": spec.dt, "radius": spec.robots.radius, "goals": self.goals, "starts": self.starts,
            "goal_tolerance": spec.goal_tolerance, "delta": spec.delta, "local_box": spec.local_box, "dim": self.dim,
            "teams": per_robot([t.name for t in teams]), "models": per_robot([t.model.kind for t in teams]),
            "controllers": per_robot([t.model.controller for t in teams]), "v_max": per_robot([t.v_max for t in teams]),
            "sigma": per_robot([t.largest_sigma() for t in teams]), "robot_cov": covs[0] if shared else None,
            "boxes": [{"center": list(b.center), "size": list(b.size), "yaw": b.yaw} for b in spec.space3d.boxes] if spec.space3d else [],
            "bounds3d": list(spec.space3d.bounds) if spec.space3d is not None else None,
        })


# ---------------------------------------------------------------------------------------
# the loop
# ---------------------------------------------------------------------------------------
def records_cells(spec: Spec, world: World) -> bool:
    """Whether the run records every robot's cell (2-D runs with cells; default N ≤ 64)."""
    if world.cell_model is None or world.dim != 2:
        return False
    return spec.record_cells if spec.record_cells is not None else world.n <= RECORD_CELLS_MAX_ROBOTS


def record_cell_log(rec: Recorder, log: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """Write the per-step cells into ``cell_A (T, N, M, 2)`` / ``cell_b (T, N, M)``, padded
    to the widest step with always-true rows ``0·p ≤ 1``."""
    m = max(a.shape[1] for a, _ in log)
    n, d = log[0][0].shape[0], log[0][0].shape[2]
    rec.step("cell_A", (n, m, d), fill=0.0)
    rec.step("cell_b", (n, m), fill=1.0)
    for k, (a_k, b_k) in enumerate(log):
        rec["cell_A"][k, :, : a_k.shape[1]] = a_k
        rec["cell_b"][k, :, : b_k.shape[1]] = b_k


def simulate(spec: Spec, seed: int | None = None, progress: bool = False) -> Trace:
    """Simulate a scenario and return its :class:`~robofleet.core.trace.Trace`.

    Parameters
    ----------
    spec:
        The validated scenario.
    seed:
        ``None`` draws a fresh seed (recorded as ``trace.seed``); every random draw of the
        run (random layouts, the robots' and obstacles' estimation noise) comes from it,
        so ``simulate(spec, seed=trace.seed)`` replays every array bit for bit.
    progress:
        Show a progress bar.

    Returns
    -------
    Trace
        Arrays ``positions (T+1, N, d)`` true positions, ``estimates (T, N, d)``,
        ``controls (T, N, w)`` (zero-padded to the widest team's inputs), ``headings
        (T+1, N)`` when a team has headings (NaN for the others), ``step_seconds (T,)``
        (cells + controllers of the whole fleet), ``arrival_steps (N,)``, the boolean
        ``estimate_in_cell (T, N)`` (the estimate lay in the robot's own cell when it was
        built, before the controller: the premise of the chance constraint) and
        ``empty_cell (T, N)`` (the cell was empty; both all-False for ORCA, which builds
        no cells); 2-D runs with
        cells record ``cell_A``/``cell_b`` (default for N ≤ 64); runs with an MPC team record
        ``mpc_status (T, N)`` int8 (0 solved, 1 fallback, 2 arrived and holding, −1 no MPC). Events ``arrived``,
        ``deadlock``, ``empty_cell``. Results: :data:`~robofleet.avoidance.metrics.RESULTS`,
        judged on every step (:class:`~robofleet.avoidance.metrics.RunTally`) even when the
        spec's ``record_every`` k > 1 keeps only the rows of steps 0, k, 2k, … (the run is
        the same whatever k). Metadata
        ``loop_seconds``: the step loop's wall time alone (without the set-up and the
        per-run results).
    """
    expect_spec(spec, Spec, "avoidance")  # input validation: a validated avoidance scenario
    seed = resolve_seed(seed)
    rng = as_generator(seed)
    world = World(spec, rng)
    rec = Recorder(spec.max_steps, world.n, label=f"{spec.method} · {world.n} robots", progress=progress, record_every=spec.record_every)
    workspace = spec.workspace.build() if spec.space3d is None else None
    tally = RunTally(spec.robots.radius, workspace, spec.space3d.box_arrays() if spec.space3d is not None else None)
    rec.state("positions", (world.n, world.dim), initial=world.positions(), watch=tally.add_state)  # results judge every step
    if world.has_headings:
        rec.state("headings", (world.n,), initial=world.headings())
    rec.step("estimates", (world.n, world.dim))
    rec.step("controls", (world.n, world.control_width))
    rec.step("estimate_in_cell", (world.n,), dtype=bool, fill=False)
    rec.step("empty_cell", (world.n,), dtype=bool, fill=False)
    cell_log: list | None = [] if records_cells(spec, world) else None
    last_estimates = [world.positions()]
    if world.has_mpc:
        rec.step("mpc_status", (world.n,), dtype=np.int8, fill=MPC_NO_MPC)

    def step(k: int) -> bool:
        estimates = world.positions() + world.position_noise(rng)
        last_estimates[0] = estimates
        shift = world.obstacle_shift(rng)
        with rec.timed(k):
            cells, controls, flags = world.decide(estimates, shift)
        flags = world.measure_premise(cells, estimates, flags)
        world.advance(controls)
        rec.put(k, estimates=estimates, controls=controls, estimate_in_cell=flags.estimate_in_cell, empty_cell=flags.cell_empty)
        tally.add_step(flags.estimate_in_cell, flags.cell_empty, rec.arrival_steps < 0)  # before arrive(k + 1): robots not yet arrived
        if world.has_mpc:
            rec.put(k, mpc_status=world.mpc_status)
        rec.put_state(k + 1, positions=world.positions())
        if world.has_headings:
            rec.put_state(k + 1, headings=world.headings())
        rec.arrive(k + 1, world.arrived())
        rec.events_for(k, "deadlock", flags.deadlocked)
        rec.events_for(k, "empty_cell", flags.empty)
        if cell_log is not None and rec.records(k):
            cell_log.append((cells.A, cells.b))
        return rec.all_arrived and world.settled(estimates)

    rec.run(step)
    loop_seconds = rec.wall_seconds - tally.seconds  # the step loop without tallying the per-run results
    if cell_log:
        record_cell_log(rec, cell_log)
    arrays = rec.arrays()
    counts = replace(world.counts(), empty_cell_steps=sum(e["kind"] == "empty_cell" for e in rec.events))
    results = tally.results(dt=spec.dt, step_seconds=arrays["step_seconds"], arrivals=arrays["arrival_steps"], counts=counts,
                            premise=world.cell_model is not None)
    results["success"] = bool(results["success"] and world.settled(last_estimates[0]))  # nobody left stepped aside
    metadata = {**world.metadata(), "loop_seconds": loop_seconds}
    return rec.trace("avoidance", scenario=spec.scenario_name, seed=seed, metadata=metadata, results=results, workspace=workspace)
