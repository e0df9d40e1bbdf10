"""The closed loop of paper 003 for single-integrator robots.

Every step (notes/buavc.md "Noise"): each robot's estimate is its TRUE position plus a
draw from ``N(0, Σ)``, and each obstacle's estimated position is its true position plus a
draw from ``N(0, Σ_o)``; every robot builds its cell from those estimates, steers with the
one-step controller, and the TRUE position moves ``p ← p + u Δt``. Collisions are judged
on true positions. Methods share this code path and differ only in what the cell uses:

* ``buavc``: Σ, Σ_o and the chance buffers (δ);
* ``bvc``: Σ = Σ_o = 0, buffer r_s (Zhou et al. 2017);
* ``bvc_inflated``: Σ = Σ_o = 0 and radius ``r_s + k σ_max`` (k = ``inflation_sigmas``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from shapely.geometry import Polygon

from ..core.progress import tracked
from ..core.rng import as_generator
from ..core.trace import Trace
from ..dynamics import single_integrator
from .buffer import confidence_quantile, shadow_epsilon
from .cell import CellGeometry, build_cells
from .controller import ControllerState, DeadlockParams, single_integrator_control
from .obstacles import ObstacleSet, wall_planes
from .scenario import Spec, sample_layout

RECORD_CELLS_MAX_ROBOTS = 64


@dataclass(frozen=True)
class MethodSetup:
    """What the cells of a method are built from."""

    robot_cov: np.ndarray      # (2, 2) Σ the cells use (zeros for BVC variants)
    radius: float              # r_s used in the buffers
    quantile: float            # Φ⁻¹(√(1 − δ)) (0 for BVC variants)
    obstacles: ObstacleSet

    def obstacle_clearance(self, obstacle_cov: np.ndarray) -> float:
        """Largest distance the cells keep a robot from a nominal obstacle boundary:
        r_s + chance buffer + ε-shadow (used to place the detour vertices of appendix C)."""
        sigma = float(np.sqrt(np.linalg.eigvalsh(self.robot_cov).max()))
        shadow = float(self.obstacles.shadow_radius.max(initial=0.0)) * float(np.sqrt(np.linalg.eigvalsh(obstacle_cov).max()))
        return self.radius + self.quantile * sigma + (shadow if np.isfinite(shadow) else 0.0)


def method_setup(spec: Spec) -> MethodSetup:
    """Cell ingredients of ``spec.method`` (see module docstring)."""
    cov = spec.robots.covariance()
    polys = [o.polygon() for o in spec.workspace.obstacles]
    if spec.method == "buavc":
        obs_cov = np.repeat(spec.workspace.obstacle_covariance()[None], len(polys), 0)
        eps = shadow_epsilon(spec.delta)
        return MethodSetup(cov, spec.robots.radius, confidence_quantile(spec.delta), ObstacleSet.build(polys, obs_cov, eps))
    nominal = ObstacleSet.build(polys, np.zeros((len(polys), 2, 2)), 0.0)
    radius = spec.robots.radius
    if spec.method == "bvc_inflated":
        radius += spec.inflation_sigmas * float(np.sqrt(np.linalg.eigvalsh(cov).max()))
    return MethodSetup(np.zeros((2, 2)), radius, 0.0, nominal)


def grown_obstacle_vertices(spec: Spec, margin: float) -> np.ndarray | None:
    """Vertices ``(O, V, 2)`` of the obstacles grown by ``margin`` (mitred), for appendix C."""
    polys = [Polygon(o.polygon()).buffer(margin, join_style="mitre") for o in spec.workspace.obstacles]
    if not polys:
        return None
    verts = [np.asarray(p.exterior.coords)[:-1] for p in polys]
    v_max = max(len(v) for v in verts)
    return np.stack([np.vstack([v, np.repeat(v[-1:], v_max - len(v), 0)]) for v in verts])


def run(spec: Spec, seed=None, progress: bool = False) -> Trace:
    """Simulate ``spec`` and return its :class:`~robofleet.core.trace.Trace`.

    Arrays: ``positions (T+1, N, 2)`` true positions, ``estimates (T, N, 2)``,
    ``controls (T, N, 2)``, ``step_seconds (T,)`` (cell + controller time of the whole
    team), ``arrival_steps (N,)``; ``cell_A``/``cell_b`` ``(T, N, M, ·)`` when cells are
    recorded (default for N ≤ 64). Same seed → same trace.

    Scenarios with another robot model, MPC, ORCA, a 3D space or teams run in
    :func:`robofleet.avoidance.models_simulation.run_models` (chosen once, here).
    """
    if spec.uses_models:
        from .models_simulation import run_models

        return run_models(spec, seed=seed, progress=progress)
    rng = as_generator(seed)
    n, dt = spec.robots.n, spec.dt
    starts, goals = sample_layout(spec, rng)
    setup = method_setup(spec)
    walls = wall_planes(spec.workspace.bounds_vertices())
    chol = noise_factor(spec.robots.covariance())
    obs_chol = noise_factor(spec.workspace.obstacle_covariance())
    covs = np.broadcast_to(setup.robot_cov, (n, 2, 2))
    radius = np.full(n, setup.radius)
    deadlock = DeadlockParams(**spec.deadlock.model_dump())
    state = ControllerState.initial(n, deadlock.window)
    grown = grown_obstacle_vertices(spec, 1.05 * setup.obstacle_clearance(spec.workspace.obstacle_covariance()))
    record_cells = spec.record_cells if spec.record_cells is not None else n <= RECORD_CELLS_MAX_ROBOTS

    pos = np.empty((spec.max_steps + 1, n, 2))
    est = np.empty((spec.max_steps, n, 2))
    ctl = np.empty((spec.max_steps, n, 2))
    seconds = np.empty(spec.max_steps)
    arrival = np.full(n, -1)
    cells_log, events = [], []
    pos[0] = starts
    steps = 0
    with tracked(spec.max_steps, f"{spec.method} · {n} robots", enabled=progress) as advance:
        for k in range(spec.max_steps):
            est[k] = pos[k] + rng.standard_normal((n, 2)) @ chol.T
            shift = rng.standard_normal((setup.obstacles.count, 2)) @ obs_chol.T
            t0 = time.perf_counter()
            geometry = CellGeometry(_shifted(setup.obstacles, shift), *walls)
            cells = build_cells(est[k], covs, radius, setup.quantile, geometry, spec.local_box)
            ctl[k], info = single_integrator_control(
                est[k], goals, cells, state, v_max=spec.robots.v_max, dt=dt,
                goal_tolerance=spec.goal_tolerance, deadlock=deadlock, grown_obstacles=grown,
            )
            seconds[k] = time.perf_counter() - t0
            pos[k + 1] = single_integrator.step(pos[k], ctl[k], dt)
            _log_events(k, info, state, arrival, events)
            if record_cells:
                cells_log.append((cells.A, cells.b))
            steps = k + 1
            advance()
            if state.arrived.all():
                break
    arrays = {
        "positions": pos[: steps + 1], "estimates": est[:steps], "controls": ctl[:steps],
        "step_seconds": seconds[:steps], "arrival_steps": arrival,
    }
    if record_cells:
        arrays.update(_pad_cells(cells_log))
    return _trace(spec, seed, arrays, events, starts, goals, state)


def noise_factor(cov: np.ndarray) -> np.ndarray:
    """``L`` with ``L Lᵀ = Σ`` for any symmetric PSD ``Σ`` (Cholesky, eigen-factor if singular)."""
    if not np.any(cov):
        return np.zeros_like(cov)
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(cov)
        return v * np.sqrt(np.maximum(w, 0.0))


def _trace(spec: Spec, seed, arrays, events, starts, goals, state: ControllerState) -> Trace:
    metadata = {
        "scenario": spec.name, "method": spec.method, "seed": _seed_repr(seed), "dt": spec.dt,
        "radius": spec.robots.radius, "goals": goals, "starts": starts, "goal_tolerance": spec.goal_tolerance,
        "delta": spec.delta, "robot_cov": spec.robots.covariance(), "n_robots": spec.robots.n, "v_max": spec.robots.v_max,
    }
    results = {"deadlock_detections": int(state.deadlocks.sum()), "empty_cell_steps": int(sum(e["kind"] == "empty_cell" for e in events))}
    return Trace("avoidance", arrays, events, metadata, results, spec.workspace.build())


def _shifted(obstacles: ObstacleSet, shift: np.ndarray) -> ObstacleSet:
    if obstacles.count == 0:
        return obstacles
    return replace(obstacles, vertices=obstacles.vertices + shift[:, None], lo=obstacles.lo + shift, hi=obstacles.hi + shift)


def _log_events(k, info, state, arrival, events):
    newly = state.arrived & (arrival < 0)
    arrival[newly] = k + 1
    for r in np.flatnonzero(newly):
        events.append({"step": k + 1, "kind": "arrived", "robot": int(r)})
    for r in np.flatnonzero(info["deadlocked"]):
        events.append({"step": k, "kind": "deadlock", "robot": int(r)})
    for r in np.flatnonzero(info["empty"] & ~state.arrived):
        events.append({"step": k, "kind": "empty_cell", "robot": int(r)})


def _pad_cells(log):
    m = max(a.shape[1] for a, _ in log)
    A = np.zeros((len(log), log[0][0].shape[0], m, 2))
    b = np.ones((len(log), log[0][0].shape[0], m))
    for k, (a_k, b_k) in enumerate(log):
        A[k, :, : a_k.shape[1]] = a_k
        b[k, :, : b_k.shape[1]] = b_k
    return {"cell_A": A, "cell_b": b}


def _seed_repr(seed):
    return seed if isinstance(seed, (int, type(None))) else repr(seed)
