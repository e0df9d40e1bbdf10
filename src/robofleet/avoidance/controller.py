"""One-step B-UAVC controller for single-integrator robots with the deadlock heuristic
of Zhu et al. 2022, appendix C (docs/theory/buavc.md "Controllers", "Deadlock heuristic").

Each step, robot i projects its (possibly temporary) goal onto its cell, ``g* = Π_Vi(g)``,
and commands ``u = min(v_max, ‖g* − p̂‖/Δt) · (g* − p̂)/‖g* − p̂‖`` (zero when the cell is
empty or once the robot has reached its goal, after which it holds its position).

Deadlock detection (ours, documented): a robot that has not arrived is stuck when,
over the last ``window`` steps of normal driving, its estimated distance to the goal
shrank by less than ``progress_fraction · v_max · window · Δt`` (estimates are noisy, so a
window is used instead of a single-step test), or when its projected goal coincides with
its estimate (an empty cell, where it holds still, does not count). The window restarts
when a recovery starts, so the recovery's own steps count towards the next window: a
recovery that did not lead to progress triggers the next one quickly (measured: in the
ten-box layout, 30 seeds, 75 % of robots arrive, against 52 % when recovery steps are
excluded). A stuck robot whose commanded speed averaged at least v_max/2 over the window
is counted as a *livelock* (moving without progress: circling or oscillating with its
neighbours), otherwise as a deadlock (held in place); both start the same recovery.
With the liveness rules (:mod:`.liveness`) and obstacles, progress is measured along the
roadmap path (:mod:`.navigation`) and the obstacle branch below is left to the roadmap.
Recovery (appendix C): if an obstacle constraint is active at ``g*``, head for the vertex
of that obstacle grown by ``r_s`` that minimises ``‖p̂ − v‖ + ‖v − g‖``, until the robot is
there (at most ``4 · recover_steps`` steps). The caller grows the obstacles by the whole
clearance the cells enforce (r_s, the chance buffer and the ε-shadow), not by r_s alone:
a vertex grown by r_s only lies inside the forbidden band and could never be reached.
Otherwise (an edge
shared with a robot, a wall, or a cell vertex) rotate the goal clockwise by 90° about the
robot, ``g_tmp = R_z(−90°)(g − p̂) + p̂``, for ``recover_steps`` steps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .cell import Cells, Kind
from .liveness import (
    LivenessParams,
    ParkingState,
    blocked_by_robot,
    parking_targets,
    right_hand_goals,
)
from .navigation import Navigation
from .projection import Projection, project_onto_cells, steer

NORMAL, ROTATE, VERTEX = 0, 1, 2
_CLOCKWISE_90 = np.array([[0.0, 1.0], [-1.0, 0.0]])  # R_z(−90°)


@dataclass(frozen=True)
class DeadlockParams:
    """Parameters of the deadlock heuristic (appendix C)."""

    enabled: bool = True
    window: int = 20
    progress_fraction: float = 0.25
    recover_steps: int = 10


@dataclass
class ControllerState:
    """Per-robot memory of the controller (a robot keeps only its own)."""

    arrived: np.ndarray
    mode: np.ndarray
    mode_left: np.ndarray
    target: np.ndarray
    goal_dist_history: np.ndarray  # (window, N) ring buffer of estimated goal distances
    step: int = 0
    deadlocks: np.ndarray = field(default=None)
    livelocks: np.ndarray = field(default=None)
    speed_history: np.ndarray = field(default=None)  # (window, N) commanded speeds
    parking: ParkingState | None = None

    @classmethod
    def initial(cls, n: int, window: int) -> ControllerState:
        return cls(
            arrived=np.zeros(n, bool),
            mode=np.zeros(n, np.int8),
            mode_left=np.zeros(n, np.int32),
            target=np.zeros((n, 2)),
            goal_dist_history=np.full((max(window, 1), n), np.nan),
            deadlocks=np.zeros(n, np.int64),
            livelocks=np.zeros(n, np.int64),
            speed_history=np.zeros((max(window, 1), n)),
        )


def single_integrator_control(
    estimates: np.ndarray,
    goals: np.ndarray,
    cells: Cells,
    state: ControllerState,
    *,
    v_max: np.ndarray,
    dt: float,
    goal_tolerance: float,
    deadlock: DeadlockParams,
    grown_obstacles: np.ndarray | None = None,
    liveness: LivenessParams | None = None,
    local_box: float = np.inf,
    navigation: Navigation | None = None,
    sigma: float = 0.0,
) -> tuple[np.ndarray, dict]:
    """Velocity commands ``(N, 2)`` for one control step; updates ``state`` in place.

    ``grown_obstacles`` holds ``(O, V, 2)`` vertices of the obstacles grown by ``r_s``
    (padded by repetition), used by the obstacle branch of the heuristic. With
    ``liveness`` enabled, arrived robots yield to lingering neighbours
    (:mod:`.liveness`); their targets are projected onto their cells like every other.
    With ``navigation`` (:mod:`.navigation`), robots steer to the next vertex of their
    shortest obstacle-free path instead of the goal itself, and progress is measured along
    that path. ``sigma`` is the largest standard deviation of the estimates the cells
    account for (0 for BVC, which ignores the noise): with ``sigma > 0`` a robot whose
    estimate lies ``liveness.band_sigmas · sigma`` beyond an obstacle face first steers
    back into its cell. Returns the commands and a dict with the projected goals, empty-cell mask and the
    robots newly detected in deadlock.
    """
    goal_dist = np.linalg.norm(goals - estimates, axis=1)
    state.arrived |= goal_dist <= goal_tolerance
    heading, to_go = (goals, goal_dist) if navigation is None else navigation.step(estimates, state.arrived)
    working_goal = _working_goal(estimates, heading, state)
    moving_parked = np.zeros(len(goals), bool)
    if liveness is not None and liveness.enabled:
        if state.parking is None:
            state.parking = ParkingState.initial(len(goals))
        parked_target, moving_parked = parking_targets(estimates, goals, state.arrived, state.parking, liveness, local_box, goal_tolerance)
        working_goal[state.arrived] = parked_target[state.arrived]
    proj = project_onto_cells(working_goal, cells)
    if liveness is not None and liveness.enabled and liveness.right_hand_angle > 0:
        proj = _right_hand(estimates, working_goal, proj, cells, state, liveness)
    if liveness is not None and liveness.enabled and sigma > 0:
        proj = _out_of_the_band(estimates, proj, cells, liveness.band_sigmas * sigma)
    u, state.speed_history[state.step % len(state.speed_history)], move_dist = steer(estimates, proj, v_max, dt, state.arrived & ~moving_parked)
    stuck = _detect_deadlock(to_go, move_dist, state, v_max, dt, deadlock)
    if stuck.any():  # the window's mean speed tells a livelock from a deadlock
        state.livelocks += stuck & (state.speed_history.mean(axis=0) >= 0.5 * v_max)
    if deadlock.enabled and stuck.any():
        detours = grown_obstacles if navigation is None else None  # the roadmap already routes around obstacles
        _start_recovery(stuck, estimates, heading, cells, proj.active, state, deadlock, detours)
    heading_vertex = np.flatnonzero(state.mode == VERTEX)  # only these robots can reach their detour vertex
    reach = max(goal_tolerance, float(np.max(v_max)) * dt)
    reached = heading_vertex[np.linalg.norm(state.target[heading_vertex] - estimates[heading_vertex], axis=1) <= reach]
    state.mode_left[reached] = 0
    state.mode_left -= state.mode != NORMAL
    state.mode[state.mode_left <= 0] = NORMAL
    state.step += 1
    return u, {"projected": proj.point, "empty": proj.empty, "deadlocked": stuck}


def cell_rows(cells: Cells, rows: np.ndarray | slice) -> Cells:
    """The cells of some robots only (an index array or a slice of the fleet)."""
    return Cells(cells.A[rows], cells.b[rows], cells.valid[rows], cells.kind[rows], cells.source[rows])


def _right_hand(estimates, working_goal, proj, cells: Cells, state: ControllerState, liveness: LivenessParams):
    """Re-project, turned right (:func:`.liveness.right_hand_goals`), the goals of the
    driving robots that a neighbour blocks (only their rows are projected again)."""
    turn = blocked_by_robot(estimates, proj.active, cells, liveness.face_near) & ~state.arrived & (state.mode == NORMAL) & ~proj.empty
    if not turn.any():
        return proj
    rows = np.flatnonzero(turn)
    goals = right_hand_goals(estimates[rows], working_goal[rows], np.deg2rad(liveness.right_hand_angle))
    turned = project_onto_cells(goals, cell_rows(cells, rows))
    keep = rows[~turned.empty]
    point, active = proj.point.copy(), proj.active.copy()
    point[keep], active[keep] = turned.point[~turned.empty], turned.active[~turned.empty]
    return Projection(point, proj.empty, active)


def _out_of_the_band(estimates: np.ndarray, proj: Projection, cells: Cells, depth: float) -> Projection:
    """A robot whose estimate lies more than ``depth`` beyond one of its cell's obstacle
    faces (deep in the band the cells keep clear, where the paper's bound does not hold)
    steers to its cell's point nearest its estimate, ``Π_Vi(p̂)``, instead of to the
    projected goal, which can lie along or across the band. Measured on the random
    scenarios: without it one run of 350 made an obstacle contact (a robot squeezed against
    an obstacle by a crowd drifted in over 200 steps); with it none, and 326/350 successes
    against 329/350. Steering back whenever the estimate is outside the cell at all
    stopped progress instead (76/150): noise alone puts it outside in 17 % of steps."""
    rows = np.arange(len(estimates))[:, None]
    slack = np.einsum("nkc,nc->nk", cells.A, estimates) - cells.b
    norm = np.maximum(np.linalg.norm(cells.A, axis=-1), 1e-12)
    deep = ~proj.empty & np.any(cells.valid & (cells.kind == Kind.OBSTACLE) & (slack / norm > depth), axis=1)
    if not deep.any():
        return proj
    idx = np.flatnonzero(deep)
    back = project_onto_cells(estimates[idx], cell_rows(cells, idx))
    point = proj.point.copy()
    point[idx] = np.where(back.empty[:, None], point[idx], back.point)
    return Projection(point, proj.empty, proj.active)


def _working_goal(estimates, goals, state: ControllerState) -> np.ndarray:
    """The goal each robot steers to this step: its goal, the rotated goal, or an obstacle vertex."""
    g = goals.copy()
    rot = state.mode == ROTATE
    if rot.any():
        g[rot] = (goals[rot] - estimates[rot]) @ _CLOCKWISE_90.T + estimates[rot]
    vert = np.flatnonzero(state.mode == VERTEX)
    g[vert] = state.target[vert]
    return g


def _detect_deadlock(goal_dist, move_dist, state: ControllerState, v_max, dt, params: DeadlockParams) -> np.ndarray:
    hist = state.goal_dist_history
    slot = state.step % len(hist)
    before = hist[slot].copy()
    hist[slot] = goal_dist
    if not params.enabled:
        return np.zeros(len(goal_dist), bool)
    min_progress = params.progress_fraction * v_max * len(hist) * dt
    slow = np.isfinite(before) & (before - goal_dist < min_progress)
    sitting = move_dist < 1e-9  # projected goal at the estimate (an empty cell passes inf)
    stuck = (slow | sitting) & ~state.arrived & (state.mode == NORMAL)
    if stuck.any():
        hist[:, stuck] = np.nan  # restart the window after a recovery
    state.deadlocks += stuck
    return stuck


def _start_recovery(stuck, estimates, goals, cells: Cells, active, state: ControllerState, params: DeadlockParams, grown):
    rows = np.flatnonzero(stuck)
    act = active[rows]
    kinds = np.where(act >= 0, cells.kind[rows[:, None], np.maximum(act, 0)], -1)
    sources = np.where(act >= 0, cells.source[rows[:, None], np.maximum(act, 0)], -1)
    on_obstacle = kinds == Kind.OBSTACLE
    use_vertex = on_obstacle.any(axis=1) & (grown is not None)
    state.mode[rows] = ROTATE
    state.mode_left[rows] = params.recover_steps
    if use_vertex.any():
        vr = rows[use_vertex]
        obstacle = sources[use_vertex][np.arange(use_vertex.sum()), np.argmax(on_obstacle[use_vertex], axis=1)]
        verts = grown[obstacle]  # (R, V, 2)
        detour = np.linalg.norm(verts - estimates[vr, None], axis=-1) + np.linalg.norm(verts - goals[vr, None], axis=-1)
        state.target[vr] = verts[np.arange(len(vr)), np.argmin(detour, axis=1)]
        state.mode[vr] = VERTEX
        state.mode_left[vr] = 4 * params.recover_steps
