"""Recovery stage: the deadlock heuristic of Zhu et al. 2022, appendix C
(docs/theory/buavc.md "Deadlock heuristic").

When the progress checker (:mod:`robofleet.avoidance.navigation.progress`) finds a robot stuck, the robot recovers:

* **Obstacle branch** (single integrators without a route): if an obstacle constraint is
  active at the projected target, head for the vertex ``v`` of that obstacle, grown by the
  whole clearance the cells keep (r_s, the chance buffer and the ε-shadow), that minimises
  ``‖p̂ − v‖ + ‖v − g‖``, until the robot is there (at most ``4 · recover_steps`` steps).
  Growing by r_s alone, as the paper writes, puts the vertex inside the band the cells keep
  clear, where it could never be reached. With a route the roadmap already goes round the
  obstacles, and this branch is left to it.
* **Rotation** (otherwise; every model): for ``recover_steps`` steps steer to the goal
  rotated clockwise by 90° about the robot, Eq. (51): ``g_tmp = R_z(−90°)(g − p̂) + p̂``.

What the stage guarantees: it only chooses targets, which the model's cell-keeping
controller keeps inside the cell; a recovery lasts a bounded number of steps
(``recover_steps``, or ``4 · recover_steps`` for a vertex), after which the robot steers to
its route's target again.
"""

from __future__ import annotations

import numpy as np

from ..cell import Cells, Kind
from .progress import DeadlockParams

NORMAL, ROTATE, VERTEX = 0, 1, 2
CLOCKWISE_90 = np.array([[0.0, 1.0], [-1.0, 0.0]])  # R_z(−90°)


def recovery_targets(estimates: np.ndarray, targets: np.ndarray, mode: np.ndarray, vertex: np.ndarray) -> np.ndarray:
    """The target each robot steers to this step: its target, the rotated target
    (Eq. (51), robots in ``ROTATE``), or its obstacle vertex (robots in ``VERTEX``);
    ``targets`` itself while no robot recovers."""
    if np.all(mode == NORMAL):
        return targets
    g = targets.copy()
    rot = mode == ROTATE
    if rot.any():
        g[rot] = (targets[rot] - estimates[rot]) @ CLOCKWISE_90.T + estimates[rot]
    vert = np.flatnonzero(mode == VERTEX)
    g[vert] = vertex[vert]
    return g


def start_recovery(stuck: np.ndarray, estimates: np.ndarray, goals: np.ndarray, cells: Cells, active: np.ndarray,
                   mode: np.ndarray, mode_left: np.ndarray, vertex: np.ndarray, params: DeadlockParams,
                   grown: np.ndarray | None) -> None:
    """Start the recovery of the ``stuck`` robots (module docstring), in place on ``mode``,
    ``mode_left`` and ``vertex``; ``grown`` ``(O, V, 2)`` are the grown obstacles' vertices
    (``None``: rotation only; then ``cells`` and ``active`` are not read)."""
    rows = np.flatnonzero(stuck)
    mode[rows] = ROTATE
    mode_left[rows] = params.recover_steps
    if grown is None:
        return
    act = active[rows]
    kinds = np.where(act >= 0, cells.kind[rows[:, None], np.maximum(act, 0)], -1)
    sources = np.where(act >= 0, cells.source[rows[:, None], np.maximum(act, 0)], -1)
    on_obstacle = kinds == Kind.OBSTACLE
    use_vertex = on_obstacle.any(axis=1)
    if use_vertex.any():
        vr = rows[use_vertex]
        obstacle = sources[use_vertex][np.arange(use_vertex.sum()), np.argmax(on_obstacle[use_vertex], axis=1)]
        verts = grown[obstacle]  # (R, V, 2)
        detour = np.linalg.norm(verts - estimates[vr, None], axis=-1) + np.linalg.norm(verts - goals[vr, None], axis=-1)
        vertex[vr] = verts[np.arange(len(vr)), np.argmin(detour, axis=1)]
        mode[vr] = VERTEX
        mode_left[vr] = 4 * params.recover_steps


def count_down(estimates: np.ndarray, mode: np.ndarray, mode_left: np.ndarray, vertex: np.ndarray, reach: float) -> None:
    """One step of every recovery: a robot within ``reach`` of its vertex ends its own;
    every recovery loses a step and ends at zero (in place; nothing to do while no robot
    recovers)."""
    if np.all(mode == NORMAL):
        return
    heading_vertex = np.flatnonzero(mode == VERTEX)
    reached = heading_vertex[np.linalg.norm(vertex[heading_vertex] - estimates[heading_vertex], axis=1) <= reach]
    mode_left[reached] = 0
    mode_left -= mode != NORMAL
    mode[mode_left <= 0] = NORMAL


def rotate_goal_clockwise(positions: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """Appendix C, Eq. (51): ``g_tmp = R_z(−90°)(g − p̂) + p̂`` (the z component is kept)."""
    rel = goals - positions
    out = rel.copy()
    out[:, 0], out[:, 1] = rel[:, 1], -rel[:, 0]
    return out + positions


class GoalRotation:
    """Appendix C detection and goal rotation for the models without the single
    integrators' memory (double integrators, unicycles, the MPC), vectorized over robots.

    A robot that has not arrived is stuck when its (estimated) position moved at most
    ``progress`` (Δp_min) over the last ``window`` steps, the net displacement
    ``‖p̂_k − p̂_{k−window}‖``, as in the authors' release; the navigated models use the
    progress checker (:class:`.progress.ProgressChecker`) instead;
    for the next ``recover_steps`` steps it steers to ``g_tmp`` (Eq. (51)), then back to
    ``g``; it is not re-flagged within ``window`` steps.
    """

    def __init__(self, n: int, window: int, progress: float, recover_steps: int):
        self.window, self.progress, self.recover_steps = window, progress, recover_steps
        self._since = np.zeros(n, np.int64)
        self._left = np.zeros(n, np.int64)
        self._history = None
        self.step_count = 0
        self.deadlocks = np.zeros(n, np.int64)

    def working_goals(self, positions: np.ndarray, goals: np.ndarray, arrived: np.ndarray | None = None) -> np.ndarray:
        """The goals to steer to this step (rotated for recovering robots); updates the detector."""
        if self._history is None:
            self._history = np.repeat(positions[None], self.window, 0)
        slot = self.step_count % self.window
        moved = np.linalg.norm(positions - self._history[slot], axis=1)
        self._history[slot] = positions
        self.step_count += 1
        done = np.zeros(len(positions), bool) if arrived is None else arrived
        self._since += 1
        stuck = (self.step_count > self.window) & (moved <= self.progress) & ~done  # net displacement at most Δp_min
        stuck &= (self._left == 0) & (self._since > self.window)
        self._left[stuck] = self.recover_steps
        self._since[stuck] = 0
        self.deadlocks += stuck
        rotating = self._left > 0
        self._left[rotating] -= 1
        return np.where(rotating[:, None], rotate_goal_clockwise(positions, goals), goals)
