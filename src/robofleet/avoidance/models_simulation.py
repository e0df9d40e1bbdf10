"""The closed loop of paper 003 for every robot model: double integrators (braking rule),
differential-drive robots (three projections), quadrotors and any model under the
B-UAVC MPC, ORCA for holonomic robots, 3-D workspaces and heterogeneous teams.

Same noise model as :mod:`.simulation` (notes/buavc.md "Noise"): every step each robot's
position estimate is its TRUE position plus a draw from ``N(0, Σ)`` (velocities, headings
and attitudes are measured exactly), each obstacle's estimated position is its true
position plus a draw from ``N(0, Σ_o)``; cells come from the estimates, the TRUE states
move, and collisions are judged on true positions.

In a 3-D space every robot's cell is built in R³ from all estimates; ground robots
(every model but the quadrotor) move in the plane ``z = z_g`` (floor + r_s) and use their
cell's section with that plane, ``{(x, y) : a_xy·(x, y) ≤ b − a_z z_g}`` (rows normalised;
rows with ``a_xy ≈ 0`` are dropped when satisfied and make the cell empty otherwise, except
the floor and ceiling walls, which do not bound ground robots).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..core.progress import tracked
from ..core.rng import as_generator
from ..core.trace import Trace
from ..dynamics import double_integrator as di
from ..dynamics import quadrotor as quad
from ..dynamics import unicycle as uni
from .braking import braking_control, braking_rule
from .buffer import buffer, confidence_quantile, shadow_epsilon
from .cell import CellGeometry, Cells, Kind, build_cells
from .cell3d import box_shadow_planes, workspace_box_planes
from .controller import ControllerState, DeadlockParams, single_integrator_control
from .diff_drive import three_projection_control
from .models_spec import ground_height, team_layouts
from .mpc import BuavcMPC, GoalRotation, SingleIntegratorParams
from .obstacles import ObstacleSet, wall_planes
from .orca import orca_velocities, preferred_velocities
from .projection import project_onto_cells
from .simulation import RECORD_CELLS_MAX_ROBOTS, _pad_cells, _seed_repr, _shifted, grown_obstacle_vertices, method_setup
from .scenario import Spec, sample_layout

CONTROL_WIDTH = 4  # controls are stored padded to the widest input (the quadrotor's)


@dataclass
class Group:
    """Robots of one model and controller (one team), with their own controller memory."""

    kind: str
    controller: str
    index: np.ndarray
    params: object
    v_max: float
    sigma: float
    flying: bool
    state: np.ndarray
    z: float | None = None  # plane of ground robots in 3-D
    mpc: BuavcMPC | None = None
    rotation: GoalRotation | None = None
    si_state: ControllerState | None = None
    arrived: np.ndarray = field(default=None)

    def positions(self, dim: int) -> np.ndarray:
        """True positions ``(n, dim)``."""
        p = self.state[:, : (3 if self.flying else 2)]
        if dim == 3 and not self.flying:
            p = np.column_stack([p, np.full(len(p), self.z)])
        return p

    @property
    def plane_dim(self) -> int:
        return 3 if self.flying else 2


def run_models(spec: Spec, seed=None, progress: bool = False) -> Trace:
    """Simulate a scenario with model blocks (see :mod:`.models_spec`); returns its Trace.

    Arrays: ``positions (T+1, N, d)``, ``estimates (T, N, d)``, ``controls (T, N, 4)``
    (zero-padded), ``headings (T+1, N)`` (NaN for robots without one), ``step_seconds``,
    ``arrival_steps``; 2-D runs with N ≤ 64 also ``cell_A``/``cell_b``.
    """
    rng = as_generator(seed)
    dim = 3 if spec.space3d is not None else 2
    starts, goals, groups = _make_groups(spec, rng, dim)
    n = len(starts)
    world = _World(spec, dim, groups, n)
    record = dim == 2 and (spec.record_cells if spec.record_cells is not None else n <= RECORD_CELLS_MAX_ROBOTS)
    T = spec.max_steps
    pos = np.empty((T + 1, n, dim))
    est = np.empty((T, n, dim))
    ctl = np.zeros((T, n, CONTROL_WIDTH))
    head = np.full((T + 1, n), np.nan)
    seconds = np.empty(T)
    arrival = np.full(n, -1)
    events, cells_log = [], []
    pos[0], head[0] = world.positions(), world.headings()
    velocity = np.zeros((n, dim))
    steps = 0
    with tracked(T, f"{spec.method} · {n} robots", enabled=progress) as advance:
        for k in range(T):
            est[k] = pos[k] + world.noise(rng)
            shift = world.obstacle_shift(rng)
            t0 = time.perf_counter()
            if spec.method == "orca":
                u_all = world.orca(est[k], velocity, goals)
                cells = None
            else:
                cells = world.cells(est[k], shift)
                u_all = world.control(est[k], goals, cells)
            seconds[k] = time.perf_counter() - t0
            velocity = world.advance(u_all)
            ctl[k] = u_all
            pos[k + 1], head[k + 1] = world.positions(), world.headings()
            _log_arrivals(k, world.arrived(), arrival, events)
            if record:
                cells_log.append((cells.A, cells.b) if cells is not None else (np.zeros((n, 1, 2)), np.ones((n, 1))))
            steps = k + 1
            advance()
            if world.arrived().all():
                break
    arrays = {"positions": pos[: steps + 1], "estimates": est[:steps], "controls": ctl[:steps], "headings": head[: steps + 1],
              "step_seconds": seconds[:steps], "arrival_steps": arrival}
    if record and cells_log:
        arrays.update(_pad_cells(cells_log))
    metadata = {
        "scenario": spec.name, "method": spec.method, "seed": _seed_repr(seed), "dt": spec.dt, "radius": spec.robots.radius,
        "goals": goals, "starts": starts, "goal_tolerance": spec.goal_tolerance, "delta": spec.delta, "dim": dim, "n_robots": n,
        "models": [g.kind for g in groups for _ in g.index], "controllers": [g.controller for g in groups for _ in g.index],
        "boxes": _boxes_metadata(spec),
        "bounds3d": list(spec.space3d.bounds) if spec.space3d is not None else None,
    }
    results = world.results(pos[: steps + 1])
    return Trace("avoidance", arrays, events, metadata, results, spec.workspace.build() if dim == 2 else None)


# ---------------------------------------------------------------------------------------
# set-up
# ---------------------------------------------------------------------------------------
def _make_groups(spec: Spec, rng, dim: int):
    if spec.teams:
        starts, goals, index = team_layouts(spec)
        teams = [(t.model, t.v_max, t.sigma, t.model.kind == "quadrotor", idx) for t, idx in zip(spec.teams, index)]
    else:
        starts, goals = sample_layout(spec, rng)
        sigma = float(np.sqrt(np.linalg.eigvalsh(spec.robots.covariance()).max()))
        teams = [(spec.model, spec.robots.v_max, sigma, False, np.arange(len(starts)))]
    groups = [_group(spec, model, v_max, sigma, flying, idx, starts[idx], goals[idx], dim) for model, v_max, sigma, flying, idx in teams]
    return starts, goals, groups


def _group(spec, model, v_max, sigma, flying, idx, starts, goals, dim) -> Group:
    n = len(idx)
    kind = model.kind
    xy = starts[:, :2]
    if kind == "single_integrator":
        params, state = SingleIntegratorParams(v_max=v_max), xy.copy()
    elif kind == "double_integrator":
        params, state = di.DoubleIntegratorParams(a_max=model.a_max, v_max=v_max), np.column_stack([xy, np.zeros((n, 2))])
    elif kind == "unicycle":
        heading = np.arctan2(goals[:, 1] - xy[:, 1], goals[:, 0] - xy[:, 0])
        params, state = uni.UnicycleParams(v_max=v_max, omega_max=model.omega_max), np.column_stack([xy, heading])
    else:
        params, state = model.quadrotor, np.column_stack([starts[:, :3], np.zeros((n, 6))])
    g = Group(kind, model.controller, idx, params, v_max, sigma, flying, state, arrived=np.zeros(n, bool))
    if dim == 3 and not flying:
        g.z = ground_height(spec)
    if spec.method == "orca":
        pass  # ORCA keeps only the arrival flags
    elif model.controller == "mpc":
        g.mpc = BuavcMPC(kind, params, dim=g.plane_dim, dt=spec.dt, config=model.mpc, n_robots=n)
    elif kind == "single_integrator":
        g.si_state = ControllerState.initial(n, spec.deadlock.window)
    else:
        d = spec.deadlock
        g.rotation = GoalRotation(n, d.window, d.progress_fraction * v_max * d.window * spec.dt, d.recover_steps)
    return g


class _World:
    """Everything the loop needs per step: noise, cells, controllers, dynamics, metrics."""

    def __init__(self, spec: Spec, dim: int, groups: list[Group], n: int):
        self.spec, self.dim, self.groups, self.n = spec, dim, groups, n
        self.dt = spec.dt
        buavc = spec.method == "buavc"
        self.quantile = confidence_quantile(spec.delta) if buavc else 0.0
        sig = np.zeros(n)
        flying = np.zeros(n, bool)
        for g in groups:
            sig[g.index], flying[g.index] = g.sigma, g.flying
        self.sigma, self.flying = sig, flying
        self.noise_dims = np.where(flying[:, None] | (np.arange(dim)[None] < 2), 1.0, 0.0)  # ground robots: no z noise
        covs = (sig**2)[:, None, None] * np.eye(dim)[None] * self.noise_dims[:, :, None]
        self.covs = covs if buavc else np.zeros_like(covs)
        self.radius = np.full(n, spec.robots.radius) + (spec.inflation_sigmas * sig if spec.method == "bvc_inflated" else 0.0)
        self.deadlock = DeadlockParams(**spec.deadlock.model_dump())
        if dim == 2:
            self.setup = method_setup(spec) if spec.method != "orca" else None
            self.walls = wall_planes(spec.workspace.bounds_vertices())
            obs_cov = spec.workspace.obstacle_covariance()
            self.obs_chol = np.linalg.cholesky(obs_cov) if obs_cov.any() else np.zeros((2, 2))
            self.n_obstacles = len(spec.workspace.obstacles)
            self.grown = grown_obstacle_vertices(spec, 1.05 * self.setup.obstacle_clearance(obs_cov)) if self.setup else None
        else:
            sp = spec.space3d
            self.walls = workspace_box_planes(sp.lower, sp.upper)
            self.empty_obstacles = ObstacleSet(np.zeros((0, 1, 3)), np.zeros((0, 3, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
            self.box_center = np.array([b.center for b in sp.boxes], float).reshape(-1, 3)
            self.box_size = np.array([b.size for b in sp.boxes], float).reshape(-1, 3)
            self.box_yaw = np.array([b.yaw for b in sp.boxes], float)
            self.box_cov = (sp.obstacle_sigma**2 * np.eye(3)) if buavc else np.zeros((3, 3))
            self.obs_chol = sp.obstacle_sigma * np.eye(3)
            self.n_obstacles = len(sp.boxes)
            self.epsilon = shadow_epsilon(spec.delta)
        self.fallback_steps = 0

    # -- sensing ------------------------------------------------------------------------
    def positions(self) -> np.ndarray:
        out = np.empty((self.n, self.dim))
        for g in self.groups:
            out[g.index] = g.positions(self.dim)
        return out

    def headings(self) -> np.ndarray:
        out = np.full(self.n, np.nan)
        for g in self.groups:
            if g.kind == "unicycle":
                out[g.index] = g.state[:, 2]
            elif g.kind == "quadrotor":
                out[g.index] = g.state[:, 8]
        return out

    def noise(self, rng) -> np.ndarray:
        return rng.standard_normal((self.n, self.dim)) * self.sigma[:, None] * self.noise_dims

    def obstacle_shift(self, rng) -> np.ndarray:
        return rng.standard_normal((self.n_obstacles, self.dim)) @ self.obs_chol.T

    def arrived(self) -> np.ndarray:
        out = np.zeros(self.n, bool)
        for g in self.groups:
            out[g.index] = g.arrived if g.si_state is None else g.si_state.arrived
        return out

    # -- cells ----------------------------------------------------------------------------
    def cells(self, est: np.ndarray, shift: np.ndarray) -> Cells:
        spec = self.spec
        if self.dim == 2:
            geometry = CellGeometry(_shifted(self.setup.obstacles, shift), *self.walls)
            return build_cells(est, self.covs, self.radius, self.quantile, geometry, spec.local_box)
        cells = build_cells(est, self.covs, self.radius, self.quantile, CellGeometry(self.empty_obstacles, *self.walls), spec.local_box)
        if self.n_obstacles == 0:
            return cells
        a, b = box_shadow_planes(est, self.box_center + shift, self.box_size, self.box_yaw, self.box_cov, self.epsilon)
        b = b - buffer(a, self.covs[:, None], self.radius[:, None], self.quantile)
        reach = 0.5 * np.linalg.norm(self.box_size, axis=1)
        near = np.all(np.abs(est[:, None] - (self.box_center + shift)[None]) <= spec.local_box + reach[None, :, None], axis=-1)
        return Cells(np.concatenate([cells.A, a], 1), np.concatenate([cells.b, np.where(near, b, 1.0)], 1),
                     np.concatenate([cells.valid, near], 1), np.concatenate([cells.kind, np.full(near.shape, int(Kind.OBSTACLE), np.int8)], 1),
                     np.concatenate([cells.source, np.broadcast_to(np.arange(self.n_obstacles), near.shape)], 1))

    # -- control ----------------------------------------------------------------------------
    def control(self, est: np.ndarray, goals: np.ndarray, cells: Cells) -> np.ndarray:
        u = np.zeros((self.n, CONTROL_WIDTH))
        for g in self.groups:
            sub = _section(_rows(cells, g.index), g.z) if (self.dim == 3 and not g.flying) else _rows(cells, g.index)
            p_est = est[g.index, : g.plane_dim]
            goal = goals[g.index, : g.plane_dim]
            control = self._group_control(g, p_est, goal, sub)
            u[g.index, : control.shape[1]] = control
        return u

    def _group_control(self, g: Group, p_est, goal, cells: Cells) -> np.ndarray:
        spec, dt = self.spec, self.dt
        if g.kind == "single_integrator" and g.controller == "one_step":
            u, _ = single_integrator_control(p_est, goal, cells, g.si_state, v_max=g.v_max, dt=dt, goal_tolerance=spec.goal_tolerance,
                                             deadlock=self.deadlock, grown_obstacles=self.grown if self.dim == 2 else None)
            return u
        g.arrived |= np.linalg.norm(goal - p_est, axis=1) <= spec.goal_tolerance
        state_est = g.state.copy()
        state_est[:, : g.plane_dim] = p_est
        if g.controller == "mpc":
            u, info = g.mpc.control(state_est, goal, cells.A, cells.b, cells.valid, arrived=g.arrived)
            self.fallback_steps += int(info["fallback"].sum())
            return u
        working = g.rotation.working_goals(p_est, goal, g.arrived)
        if g.kind == "double_integrator":
            proj = project_onto_cells(working, cells)
            target = np.where(proj.empty[:, None], p_est, proj.point)
            u, _ = braking_rule(p_est, g.state[:, 2:], target, cells.A, cells.b, cells.valid, g.params, dt)
            return np.where(g.arrived[:, None], braking_control(g.state[:, 2:], g.params.a_max, dt), u)
        u = three_projection_control(state_est, working, cells.A, cells.b, cells.valid, g.params, dt, project=_project_2d)
        return np.where(g.arrived[:, None], 0.0, u)

    def orca(self, est: np.ndarray, velocity: np.ndarray, goals: np.ndarray) -> np.ndarray:
        (g,) = self.groups
        g.arrived |= np.linalg.norm(goals - est, axis=1) <= self.spec.goal_tolerance
        pref = np.where(g.arrived[:, None], 0.0, preferred_velocities(est, goals, g.v_max, self.dt))
        v, _ = orca_velocities(est, velocity, pref, self.radius, g.v_max, self.spec.orca, self.dt)
        u = np.zeros((self.n, CONTROL_WIDTH))
        u[:, :2] = v
        return u

    # -- dynamics ----------------------------------------------------------------------------
    def advance(self, u: np.ndarray) -> np.ndarray:
        """Move every TRUE state one step; returns the realised velocities ``(N, d)``."""
        before = self.positions()
        for g in self.groups:
            ug = u[g.index]
            if g.kind == "single_integrator":
                g.state = g.state + ug[:, :2] * self.dt
            elif g.kind == "double_integrator":
                g.state = di.step(g.state, ug[:, :2], self.dt, g.params)
            elif g.kind == "unicycle":
                g.state = uni.step(g.state, ug[:, :2], self.dt, g.params)
            else:
                g.state = quad.step(g.state, ug, self.dt, g.params)
        return (self.positions() - before) / self.dt

    # -- metrics -------------------------------------------------------------------------------
    def results(self, positions: np.ndarray) -> dict:
        deadlocks = 0
        for g in self.groups:
            if g.si_state is not None:
                deadlocks += int(g.si_state.deadlocks.sum())
            elif g.mpc is not None:
                deadlocks += int(g.mpc.deadlocks.sum())
            elif g.rotation is not None:
                deadlocks += int(g.rotation.deadlocks.sum())
        out = {"deadlock_detections": deadlocks, "mpc_fallback_steps": self.fallback_steps}
        if self.dim == 3 and self.n_obstacles:
            dist = box_distance(positions, self.box_center, self.box_size, self.box_yaw)  # (T, N, O)
            hits = dist.min(axis=2) < self.spec.robots.radius - 1e-7
            out["min_obstacle_distance"] = float(dist.min())
            out["obstacle_collisions"] = int(hits.any(axis=0).sum())
            if out["obstacle_collisions"]:
                out["success"] = False  # the generic summary does not see 3D boxes
        return out


def _rows(cells: Cells, index: np.ndarray) -> Cells:
    return Cells(cells.A[index], cells.b[index], cells.valid[index], cells.kind[index], cells.source[index])


def _section(cells: Cells, z: float) -> Cells:
    """The section of 3-D cells with the plane ``z`` (ground robots), as 2-D cells."""
    a_xy = cells.A[..., :2]
    norm = np.linalg.norm(a_xy, axis=-1)
    b = cells.b - cells.A[..., 2] * z
    flat = norm < 1e-9
    keep = cells.valid & ~(flat & ((b >= 0) | (cells.kind == int(Kind.WALL))))  # floor and ceiling do not bound ground robots
    A = np.where(flat[..., None], 0.0, a_xy / np.where(flat, 1.0, norm)[..., None])
    b = np.where(flat, np.where(b >= 0, 1.0, b), b / np.where(flat, 1.0, norm))
    return Cells(A, np.where(keep, b, 1.0), keep, cells.kind, cells.source)


def _project_2d(points, A, b, valid):
    proj = project_onto_cells(points, Cells(A, b, valid, np.zeros(valid.shape, np.int8), np.zeros(valid.shape, np.intp)))
    return np.where(proj.empty[:, None], points, proj.point), ~proj.empty


def box_distance(points: np.ndarray, centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray) -> np.ndarray:
    """Euclidean distance ``(..., O)`` from points ``(..., 3)`` to yawed boxes (0 inside)."""
    rel = points[..., None, :] - centers
    c, s = np.cos(yaws), np.sin(yaws)
    local = np.stack([c * rel[..., 0] + s * rel[..., 1], -s * rel[..., 0] + c * rel[..., 1], rel[..., 2]], -1)
    return np.linalg.norm(np.maximum(np.abs(local) - 0.5 * sizes, 0.0), axis=-1)


def _boxes_metadata(spec: Spec):
    if spec.space3d is None:
        return []
    return [{"center": list(b.center), "size": list(b.size), "yaw": b.yaw} for b in spec.space3d.boxes]


def _log_arrivals(k, arrived, arrival, events):
    newly = arrived & (arrival < 0)
    arrival[newly] = k + 1
    for r in np.flatnonzero(newly):
        events.append({"step": k + 1, "kind": "arrived", "robot": int(r)})


__all__ = ["run_models", "box_distance", "replace"]
