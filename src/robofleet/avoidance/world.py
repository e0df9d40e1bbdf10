"""The fleet at run time: starts and goals, the noise, the fleet's cells, the teams with
their navigation pipelines and dynamics (Zhu et al. 2022; docs/theory/buavc.md).

Every step (docs/theory/buavc.md "Noise"): each robot's position estimate is its TRUE
position plus a draw from ``N(0, Σ)`` (velocities, headings and attitudes are measured
exactly), and each obstacle's estimated position is its true position plus a draw from
``N(0, Σ_o)`` (:meth:`World.position_noise`, :meth:`World.obstacle_shift`); every robot
builds its cell from those estimates (:mod:`.cell_model`), its team's navigation pipeline
(:mod:`.navigation.pipeline`: the stages that choose the target, then the model's
cell-keeping controller) picks the input (:meth:`World.decide`), and the TRUE states move
with the team's dynamics (:meth:`World.advance`). ORCA (van den Berg et al. 2011) builds no
cells and drives 2-D single integrators by its velocities.

Cell-keeping controllers, per model: single integrators — the one-step controller
(appendix C); double integrators — the braking rule (Sec. 5.2, :mod:`.braking`), whose
robots' cell rows are built from their braking segments (:mod:`.segment_cells`,
:meth:`World.braking_stops`); differential-drive robots — three projections (Sec. 5.3,
:mod:`.diff_drive`); quadrotors, and any model with ``controller: mpc`` — the B-UAVC MPC
(Sec. 5.4, :mod:`.mpc`).

The authors' main setup — one 2-D team of single integrators under the one-step
controller — has one team whose rows are views of the fleet's cells (no per-step copies),
which keeps the 50,000-robot step of ``benchmarks/avoidance_scale.py`` as fast as a
dedicated loop.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..core.trace import to_plain
from ..dynamics import double_integrator as di
from ..dynamics import quadrotor as quad
from ..dynamics import single_integrator
from ..dynamics import unicycle as uni
from .braking import stopping_point
from .cell import Cells, cell_rows
from .cell3d import shadow_radius
from .cell_model import (
    cell_model,
    empty_cells,
    grown_obstacle_vertices,
    ground_footprints,
    ground_section,
    method_setup,
    noise_factor,
    obstacle_clearance,
    team_covariance,
    team_noise_factor,
)
from .kernels import row_products
from .layout import initial_layout
from .metrics import ControllerCounts
from .mpc import BuavcMPC, SingleIntegratorParams
from .navigation import NavigationParams, StepState, TeamNavigation, pipeline_of
from .navigation.detour import Detours
from .navigation.params import from_mapping
from .navigation.pipeline import MPC_NO_MPC, PIPELINES
from .navigation.progress import DeadlockParams
from .navigation.route import Roadmap, Route
from .orca import orca_velocities, preferred_velocities
from .orca_obstacles import ObstacleEdges
from .spec import Spec, TeamSpec

CONTROL_WIDTH = {"single_integrator": 2, "double_integrator": 2, "unicycle": 2, "quadrotor": 4}
"""Inputs per model; the ``controls`` array is as wide as the widest team's (zero-padded)."""


def navigation_params(spec: Spec) -> NavigationParams:
    """The navigation stages' parameters of a scenario (its ``navigation:`` block)."""
    return from_mapping(spec.navigation.model_dump())


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
    nav: TeamNavigation | None = field(default=None, repr=False)  # None for ORCA

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
        return self.arrived if self.nav is None else self.nav.arrived

    def deadlock_counts(self) -> np.ndarray:
        """Deadlock detections per robot so far (appendix C)."""
        return np.zeros(len(self.arrived), np.int64) if self.nav is None else self.nav.deadlock_counts()

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


def make_group(spec: Spec, team: TeamSpec, index: slice, starts: np.ndarray, goals: np.ndarray) -> Group:
    """A team's initial state (at rest; unicycles facing their goal), without its navigation."""
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
    group = Group(team.name, kind, model.controller, index, params, team.v_max, team.flying, state, np.zeros(n, bool))
    if spec.space3d is not None and not team.flying:
        group.z = spec.ground_height()
    return group


def keeper(spec: Spec, team: TeamSpec, group: Group) -> object:
    """What a team's cell-keeping controller needs: the model's parameters, or its MPC."""
    if group.controller != "mpc":
        return group.params
    return BuavcMPC(group.kind, group.params, dim=group.plane_dim, dt=spec.dt, config=team.model.mpc, n_robots=team.n,
                    speed_limit=team.v_max if group.kind == "quadrotor" else None, position_sigma=team.largest_sigma())


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
        self.navigation_params = navigation_params(spec)
        self.deadlock = DeadlockParams(**spec.deadlock.model_dump())
        self.groups = [make_group(spec, team, sl, self.starts[sl], self.goals[sl]) for team, sl in zip(teams, slices)]
        if spec.method != "orca":  # ORCA keeps only the arrival flags
            for team, sl, g in zip(teams, slices, self.groups):
                g.nav = self.team_navigation(team, g, self.goals[sl])
        self.noise_factor = self.position_noise_factor(teams, slices)
        self.obstacle_factor, self.n_obstacles = self.obstacle_noise()
        self.radius = np.full(self.n, spec.robots.radius)
        self.v_max = np.concatenate([np.full(t.n, t.v_max) for t in teams])
        self.control_width = max(CONTROL_WIDTH[t.model.kind] for t in teams)
        self.velocity = np.zeros((self.n, self.dim))
        self.has_mpc = any(t.model.controller == "mpc" for t in teams)

    @property
    def mpc_status(self) -> np.ndarray:
        """Each robot's MPC status this step (:data:`~.navigation.pipeline.MPC_NO_MPC` for robots without one)."""
        out = np.full(self.n, MPC_NO_MPC, np.int8)
        for g in self.groups:
            if g.nav is not None:
                out[g.index] = g.nav.mpc_status
        return out

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

    def team_navigation(self, team: TeamSpec, group: Group, goals: np.ndarray) -> TeamNavigation:
        """A team's navigation (:mod:`.navigation`): its pipeline, its route and detours
        when its pipeline has them, its recovery vertices and its cell-keeping controller."""
        pipeline = pipeline_of(team.model.kind, team.model.controller)
        nav = TeamNavigation(pipeline, self.navigation_params, self.deadlock, team.n, team.v_max, self.dt, self.spec.goal_tolerance,
                             self.spec.local_box, sigma=self.team_sigma(team), keeper=keeper(self.spec, team, group))
        nav.grown = self.detour_vertices(team)
        if "route" in PIPELINES[pipeline]:
            nav.route, nav.detours = self.route(team, goals, "detour" in PIPELINES[pipeline])
        return nav

    def retarget(self, which: np.ndarray) -> None:
        """After new goals were written to ``self.goals`` for the robots ``which``: their
        arrival unlatched and their team's route (and detours) planned to the new goals."""
        for team, g in zip(self.spec.team_specs(), self.groups):
            local = which[(which >= g.index.start) & (which < g.index.stop)] - g.index.start
            if len(local) == 0:
                continue
            g.arrived[local] = False
            if g.nav is not None:
                g.nav.arrived[local] = False
                if g.nav.route is not None:
                    g.nav.route, g.nav.detours = self.route(team, self.goals[g.index], "detour" in PIPELINES[g.nav.pipeline])

    def detour_vertices(self, team: TeamSpec) -> np.ndarray | None:
        """Appendix C detour targets of a 2-D single-integrator team: the obstacles grown
        by 1.05 × the whole clearance its cells keep (r_s, the chance buffer, the ε-shadow)."""
        clearance = self.obstacle_clearance(team)
        if clearance is None or team.model.kind != "single_integrator" or team.model.controller != "one_step":
            return None
        return grown_obstacle_vertices(self.plane_obstacles()[0], 1.05 * clearance)

    def route(self, team: TeamSpec, goals: np.ndarray, with_detours: bool) -> tuple[Route | None, Detours | None]:
        """The route stage of a 2-D or ground team (:mod:`.navigation.route`) when the
        navigation asks for it and there are obstacles, and its detour stage
        (:mod:`.navigation.detour`, discs of the pair clearance ``2 β`` the cells keep
        between two estimates: r_s + the chance buffer, twice)."""
        clearance = self.obstacle_clearance(team)
        polygons, bounds = self.plane_obstacles()
        params = self.navigation_params
        if clearance is None or not polygons or not (params.enabled and params.route.enabled):
            return None, None
        r = params.route
        roadmap = Roadmap(polygons, r.node_factor * clearance, bounds, clearance, r.passage_sigmas * self.team_sigma(team),
                          sight_factor=r.sight_factor, gap_factor=r.gap_factor)
        route = Route(roadmap, goals[:, :2])
        if not (with_detours and params.detour.enabled):
            return route, None
        sigma = self.team_sigma(team)
        pair = 2.0 * (self.setup.cell_radius(self.spec.robots.radius, sigma) + self.setup.quantile * sigma)
        return route, Detours(roadmap, goals[:, :2], pair, self.spec.local_box, params.detour, params.yielding)

    def team_sigma(self, team: TeamSpec) -> float:
        """The largest standard deviation of a team's position estimate the cells account
        for (0 for the deterministic methods)."""
        return team.largest_sigma() if self.setup.chance_constrained else 0.0

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
        return row_products(z, self.noise_factor.T) if self.noise_factor.ndim == 2 else np.einsum("nij,nj->ni", self.noise_factor, z)

    def estimates(self, rng: np.random.Generator) -> np.ndarray:
        """Position estimates ``(N, d)``: the TRUE positions plus one :meth:`position_noise`
        draw, added into the draw (no third array of the fleet's size; ``x + y = y + x``
        in floating point)."""
        estimates = self.position_noise(rng)
        estimates += self.positions()
        return estimates

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
        """Deadlock detections per robot so far (a new array, not updated by later steps)."""
        return np.concatenate([g.deadlock_counts() for g in self.groups])

    # -- deciding ---------------------------------------------------------------------------
    def decide(self, estimates: np.ndarray, obstacle_shift: np.ndarray) -> tuple[Cells | None, np.ndarray, StepFlags]:
        """Every robot's cell and input for this step: ``(cells, controls (N, width), flags)``."""
        before = self.deadlock_counts()
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
        braking = [g for g in self.groups if g.kind == "double_integrator" and g.controller != "mpc"]
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
        """Inputs of one team from its navigation pipeline (:mod:`.navigation.pipeline`), and
        its robots whose cell was empty (``None`` when the controller does not find out;
        :func:`empty_cells` then decides)."""
        p_est = estimates[g.index, : g.plane_dim]
        if g.state.shape[1] == g.plane_dim:
            state_est = p_est
        else:
            state_est = g.state.copy()
            state_est[:, : g.plane_dim] = p_est
        step = StepState(p_est, self.goals[g.index, : g.plane_dim], cells, state_est)
        g.nav.decide(step)
        return step.u, step.empty

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

    def home(self) -> np.ndarray:
        """``(N,)``: which robots are home (:class:`.navigation.goal.GoalChecker`: within the
        tolerance by their estimate when they last held; ORCA: arrived)."""
        if len(self.groups) == 1:
            g = self.groups[0]
            return g.arrived if g.nav is None else g.nav.goal.home
        return np.concatenate([g.arrived if g.nav is None else g.nav.goal.home for g in self.groups])

    def counts(self) -> ControllerCounts:
        """The controllers' counters (deadlocks, MPC fallbacks; empty cells are counted from events)."""
        navs = [g.nav for g in self.groups if g.nav is not None]
        return ControllerCounts(deadlock_detections=int(self.deadlock_counts().sum()),
                                livelock_detections=sum(int(nav.livelock_count.sum()) for nav in navs),
                                mpc_fallback_steps=sum(nav.fallback_steps for nav in navs),
                                mpc_solve_steps=sum(nav.solve_steps for nav in navs))

    def metadata(self) -> dict:
        """What is needed to interpret the arrays (viz, metrics, replays), as plain JSON values.
        The per-robot lists repeat each team's plain value (one conversion per team, not
        per robot: converting a million robots' lists one element at a time took seconds)."""
        spec, teams = self.spec, self.spec.team_specs()
        covs = [team_covariance(t, self.dim) for t in teams]
        per_robot = lambda values: [v for t, v in zip(teams, to_plain(list(values))) for _ in range(t.n)]  # noqa: E731
        shared = self.dim == 2 and covs[0].ndim == 2 and all(np.array_equal(c, covs[0]) for c in covs)
        head = to_plain({
            "method": spec.method, "dt": spec.dt, "radius": spec.robots.radius, "goals": self.goals, "starts": self.starts,
            "goal_tolerance": spec.goal_tolerance, "delta": spec.delta, "local_box": spec.local_box, "dim": self.dim,
        })
        robots = {"teams": per_robot([t.name for t in teams]), "models": per_robot([t.model.kind for t in teams]),
                  "controllers": per_robot([t.model.controller for t in teams]), "v_max": per_robot([t.v_max for t in teams]),
                  "sigma": per_robot([t.largest_sigma() for t in teams])}
        tail = to_plain({
            "robot_cov": covs[0] if shared else None,
            "boxes": [{"center": list(b.center), "size": list(b.size), "yaw": b.yaw} for b in spec.space3d.boxes] if spec.space3d else [],
            "bounds3d": list(spec.space3d.bounds) if spec.space3d is not None else None,
        })
        return {**head, **robots, **tail}
