"""Liveness for B-UAVC: rules that get every robot home (docs/theory/buavc.md "Liveness rules").

The authors' controllers (docs/theory/buavc.md "Controllers", "Deadlock heuristic") stop a
robot for good at its goal and react to a deadlock only after it is detected, with a
90° goal rotation or a detour to one vertex of the blocking obstacle. Four rules, all
decentralized and communication-free, replace that where it fails:

1. **Roadmap sub-goals** (:mod:`.navigation`): a robot steers to the next vertex of its
   shortest path around the known obstacles instead of to its goal, so a box between a
   robot and its goal is never a local minimum (this replaces the appendix-C vertex
   branch; progress is measured along that path).
2. **The right-hand rule** (Zhou et al., RA-L 2017, for BVC): a driving robot whose
   projected goal lies on a face shared with a neighbour, within ``face_near`` of its
   estimate, turns its goal clockwise by ``right_hand_angle`` (:func:`right_hand_goals`);
   as every robot veers the same way, head-on pairs pass and crowds that meet at one
   point circulate as in a roundabout. Not for unicycles (measured: their
   three-projection controller then drives arcs into the walls: on diff_drive seeds
   0–19, 16/20 successes with the turn against 19/20 without; seeds 20–59, 29/40 with
   all rules against 38/40 for the paper's controller).
3. **Arrived robots yield** (:func:`parking_targets`; the idea of the issue's
   prototype, the rule and its thresholds ours): a parked robot whose neighbour lingers
   within ``near`` steps aside — away from that neighbour and ``aside_turn`` to its left,
   the side a right-hand neighbour does not take — stays aside while the neighbour
   lingers, returns to its goal when the way is clear, and backs off exponentially, so
   two parked robots never yield to each other for ever. A run ends (and succeeds) only
   when every robot has arrived and none is away from its goal on a yield
   (:meth:`ParkingState.settled`).
4. **Detours around still neighbours** (:mod:`.detour`, ours): a blocked robot treats
   the neighbours it sees holding still (parked or stuck) as discs of the pair clearance
   and re-plans its roadmap route around them, so a gap a parked robot closes is passed
   the other way round (``detour``, ``detour_steps``).

A robot uses only its own estimate and goal, the map, and the estimates of the
neighbours it sees (those in its local box R_loc). Every target is projected onto the
robot's own cell (:func:`~robofleet.avoidance.projection.project_onto_cells`), or
handed to the model's own cell-keeping controller, so the command keeps the next
position inside the cell exactly as the paper's controller does: the chance constraint
is never traded for liveness.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .cell import Kind
from .projection import project_onto_cells

HOLD, YIELD, RETURN = 0, 1, 2


@dataclass(frozen=True)
class LivenessParams:
    """Parameters of the liveness rules (module docstring).

    Attributes
    ----------
    enabled: whether the liveness rules run at all (off: the paper's controller).
    roadmap: steer to roadmap sub-goals around the obstacles (:mod:`.navigation`).
    near: neighbour distance [m] that counts as lingering near a parked robot.
    linger_steps: consecutive steps a neighbour must linger before the robot yields
        (or, while it yields, before it moves further aside).
    aside: distance [m] a yielding robot moves away from the lingering neighbours.
    max_aside: largest distance [m] from its goal a yielding robot goes.
    aside_turn: how far [deg] the step aside turns counter-clockwise from straight away.
    clear_steps: steps without any neighbour within ``near`` before it returns.
    max_yield_steps: most steps one yield lasts (two parked robots that see each other
        never clear).
    still_radius, still_steps: a neighbour whose estimate stays within ``still_radius``
        [m] of its running mean for ``still_steps`` steps holds still (parked, most
        likely) and is not yielded to (about 4σ at the shipped σ = 0.1 m). Used for
        single integrators only: a blocked single integrator keeps moving at full speed,
        a blocked double integrator or unicycle comes to rest and would look parked.
    return_steps: most steps it drives back to its goal before holding again.
    right_hand_angle: how far [deg] a robot blocked by a neighbour turns its goal clockwise.
    face_near: a neighbour's face closer than this [m] to the estimate counts as blocking.
    detour: blocked robots re-plan around neighbours that hold still (:mod:`.detour`).
    detour_steps: the most steps one such re-plan lasts.
    passage_sigmas: the roadmap closes gaps between obstacles narrower than
        1.8 × (the cells' clearance + this many σ of the position estimate), which a
        jittering estimate cannot pass (:mod:`.navigation`).
    band_sigmas: a single integrator whose estimate lies more than this many σ beyond an
        obstacle face of its cell steers back into the cell first
        (:func:`~robofleet.avoidance.controller.single_integrator_control`).
    """

    enabled: bool = False
    roadmap: bool = True
    near: float = 1.5
    linger_steps: int = 30
    aside: float = 0.6
    max_aside: float = 1.5
    aside_turn: float = 45.0
    clear_steps: int = 20
    max_yield_steps: int = 150
    still_radius: float = 0.4
    still_steps: int = 50
    return_steps: int = 200
    right_hand_angle: float = 45.0
    face_near: float = 0.5
    detour: bool = True
    detour_steps: int = 300
    passage_sigmas: float = 1.5
    band_sigmas: float = 2.0


@dataclass
class StillTracker:
    """Running mean and still count of every estimate, as the neighbours see it: an estimate
    holds still after ``steps`` consecutive steps within ``radius`` of its running mean
    (time constant ``steps / 2``). The yielding rule and :mod:`.detour` share it."""

    mean: np.ndarray
    still: np.ndarray

    @classmethod
    def initial(cls, n: int, dim: int = 2) -> StillTracker:
        return cls(np.full((n, dim), np.nan), np.zeros(n, np.int32))

    def observe(self, estimates: np.ndarray, radius: float, steps: int) -> np.ndarray:
        """Update with this step's estimates; return the still counts ``(N,)``."""
        fresh = ~np.isfinite(self.mean[:, 0])
        self.mean[fresh] = estimates[fresh]
        self.mean += (estimates - self.mean) * (2.0 / steps)
        near_mean = np.linalg.norm(estimates - self.mean, axis=1) < radius
        self.still = np.where(near_mean, self.still + 1, 0)
        return self.still


@dataclass
class ParkingState:
    """Per-robot memory of the yielding rule (a robot keeps only its own)."""

    mode: np.ndarray
    mode_left: np.ndarray
    linger: np.ndarray
    clear: np.ndarray
    target: np.ndarray
    yields: np.ndarray
    stillness: StillTracker  # what the neighbours see of each robot's estimate

    def observe(self, estimates: np.ndarray, params: LivenessParams) -> np.ndarray:
        """Update what the neighbours see of each robot and return which robots look
        parked: held still (:class:`StillTracker`) for ``still_steps`` steps."""
        return self.stillness.observe(estimates, params.still_radius, params.still_steps) >= params.still_steps

    def settled(self, estimates: np.ndarray, goals: np.ndarray, tolerance: float) -> bool:
        """Every robot that is stepping aside or returning is still (or again) within
        ``3 · tolerance`` of its goal by its estimate."""
        away = np.linalg.norm(estimates - goals, axis=1) > 3 * tolerance
        return not bool(np.any((self.mode != HOLD) & away))

    @classmethod
    def initial(cls, n: int, dim: int = 2) -> ParkingState:
        counters = [np.zeros(n, np.int32) for _ in range(3)]
        return cls(np.zeros(n, np.int8), *counters, np.zeros((n, dim)), np.zeros(n, np.int64), StillTracker.initial(n, dim))


def close_pairs(estimates: np.ndarray, near: float, local_box: float = np.inf) -> np.ndarray:
    """``(P, 2)`` ordered pairs ``(i, j)``, ``i ≠ j``, whose estimates lie within
    ``near`` of each other (and within robot i's local box R_loc): k-d tree, O(N log N)."""
    pairs = cKDTree(estimates).query_pairs(near, output_type="ndarray").reshape(-1, 2)
    if np.isfinite(local_box):
        pairs = pairs[np.all(np.abs(estimates[pairs[:, 0]] - estimates[pairs[:, 1]]) <= local_box, axis=1)]
    return np.concatenate([pairs, pairs[:, ::-1]])


def away_directions(estimates: np.ndarray, pairs: np.ndarray, turn: float = 0.0) -> np.ndarray:
    """Mean unit direction from each robot's close neighbours to it (zero when they
    cancel), turned counter-clockwise by ``turn`` [rad]: a neighbour that keeps the
    right-hand rule passes on its own right, so the parked robot clears the way by moving
    to that neighbour's left."""
    c, s = np.cos(turn), np.sin(turn)
    diff = (estimates[pairs[:, 0]] - estimates[pairs[:, 1]]) @ np.array([[c, -s], [s, c]]).T
    away = np.zeros_like(estimates)
    np.add.at(away, pairs[:, 0], diff / np.maximum(np.linalg.norm(diff, axis=1, keepdims=True), 1e-12))
    norm = np.linalg.norm(away, axis=1, keepdims=True)
    return np.where(norm > 1e-9, away / np.maximum(norm, 1e-12), 0.0)


def aside_points(origin: np.ndarray, goals: np.ndarray, away: np.ndarray, aside: float, max_aside: float) -> np.ndarray:
    """``origin + aside · away``, pulled back to within ``max_aside`` of the goal."""
    point = origin + aside * away
    offset = point - goals
    dist = np.linalg.norm(offset, axis=1, keepdims=True)
    return goals + offset * np.minimum(1.0, max_aside / np.maximum(dist, 1e-12))


def parking_targets(estimates: np.ndarray, goals: np.ndarray, parked: np.ndarray, state: ParkingState,
                    params: LivenessParams, local_box: float = np.inf, tolerance: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Advance the yielding rule one step; return each parked robot's target and which
    parked robots move this step (``(N, 2)``, ``(N,)``; rows of robots not parked are
    their goals and ``False``).

    HOLD → YIELD once a neighbour that does not hold still (:meth:`ParkingState.observe`:
    B-UAVC robots tell their neighbours apart anyway, since each neighbour's Σ_j enters
    its separator) has lingered within ``near`` for ``linger_steps``
    steps — ``2^k · linger_steps`` after the robot's k-th yield, so two robots parked
    close together, which see each other linger, do not yield to each other forever —
    (a leaky count: a step with nobody near takes one off, so estimation noise that
    carries a blocked neighbour just beyond ``near`` does not restart it): the
    target moves ``aside`` away from the lingering neighbours (from the goal). While
    yielding, a neighbour that lingers as long again pushes the target ``aside`` further
    (at most ``max_aside`` from the goal); ``clear_steps`` steps with nobody near end the
    yield, and so do ``max_yield_steps`` steps aside: RETURN drives back to the goal until the estimate is within ``tolerance`` of
    it (at most ``return_steps`` steps), then HOLD. A holding robot whose estimate lies
    more than ``3 · tolerance`` from its goal drives back too.

    Parameters
    ----------
    estimates, goals:
        ``(N, 2)`` position estimates and goals of the team.
    parked:
        ``(N,)`` robots that have arrived.
    state:
        The rule's memory, updated in place.
    params:
        :class:`LivenessParams`.
    local_box:
        Half-width R_loc of the box within which a robot sees neighbours.
    tolerance:
        The goal tolerance: a returning robot holds once its estimate is this close.
    """
    parked_like = state.observe(estimates, params)
    pairs = close_pairs(estimates, params.near, local_box) if parked.any() else np.zeros((0, 2), np.int64)
    pairs = pairs[~parked_like[pairs[:, 1]]]  # a neighbour that holds still is not waiting to pass
    crowded = np.bincount(pairs[:, 0], minlength=len(estimates)) > 0
    state.mode[~parked] = HOLD
    state.mode_left -= state.mode != HOLD
    home = np.linalg.norm(estimates - goals, axis=1) <= tolerance
    state.mode[(state.mode == RETURN) & ((state.mode_left <= 0) | home)] = HOLD
    waiting = parked & (state.mode != RETURN)
    state.linger = np.where(waiting, np.maximum(state.linger + np.where(crowded, 1, -1), 0), 0)
    state.clear = np.where(parked & (state.mode == YIELD) & ~crowded, state.clear + 1, 0)
    backoff = np.where(state.mode == HOLD, 2.0 ** np.minimum(state.yields, 20), 1.0)
    push = waiting & (state.linger >= params.linger_steps * backoff)
    if push.any():
        origin = np.where((state.mode == YIELD)[:, None], state.target, goals)
        moved = aside_points(origin, goals, away_directions(estimates, pairs, np.deg2rad(params.aside_turn)), params.aside, params.max_aside)
        start = push & (state.mode == HOLD)
        state.yields += start
        state.mode_left[start] = params.max_yield_steps
        state.target[push], state.mode[push], state.linger[push] = moved[push], YIELD, 0
    done = (state.mode == YIELD) & ((state.clear >= params.clear_steps) | (state.mode_left <= 0))
    state.mode[done], state.mode_left[done] = RETURN, params.return_steps
    target = np.where((state.mode == YIELD)[:, None], state.target, goals)
    away = np.linalg.norm(estimates - goals, axis=1) > 3 * tolerance  # e.g. pushed off by noise-driven drift
    return target, parked & ((state.mode != HOLD) | away)


def blocked_by_robot(estimates: np.ndarray, active: np.ndarray, cells, near: float) -> np.ndarray:
    """``(N,)``: an active constraint at the projected goal is a face shared with a
    neighbour (:attr:`Kind.ROBOT`) and the robot's estimate lies within ``near`` of it."""
    rows = np.arange(len(estimates))[:, None]
    act = np.maximum(active, 0)
    a, b = cells.A[rows, act], cells.b[rows, act]  # (N, 2, 2), (N, 2)
    gap = (b - np.einsum("nkc,nc->nk", a, estimates)) / np.maximum(np.linalg.norm(a, axis=-1), 1e-12)
    robot_face = (active >= 0) & (cells.kind[rows, act] == Kind.ROBOT) & (gap < near)
    return robot_face.any(axis=1)


def right_hand_goals(estimates: np.ndarray, goals: np.ndarray, angle: float) -> np.ndarray:
    """The goals turned clockwise by ``angle`` [rad] about each robot: every robot that a
    neighbour blocks veers the same way (the right-hand rule of Zhou et al., RA-L 2017),
    so a crowd crossing one point turns into a roundabout."""
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, s], [-s, c]])
    return (goals - estimates) @ turn.T + estimates


def steering_goals(estimates: np.ndarray, goals: np.ndarray, arrived: np.ndarray, cells, params: LivenessParams,
                   parking: ParkingState, local_box: float = np.inf, navigation=None, tolerance: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """The goals a team of double integrators or unicycles steers to this step under the
    liveness rules, and which arrived robots move (``(N, 2)``, ``(N,)``).

    The same rules as the single-integrator controller
    (:func:`~robofleet.avoidance.controller.single_integrator_control`): the roadmap
    sub-goal instead of the goal (``navigation``), the right-hand turn when a
    neighbour's face blocks the projected goal, and yielding by arrived robots
    (:func:`parking_targets`). The model's own controller then projects the result onto
    the cell, so its in-cell guarantee is unchanged. The turn is not taken when the turned
    goal projects onto an obstacle's face: in a lane between an obstacle on its right and
    a neighbour on its left, a double integrator turned into the obstacle and stopped
    there (measured, ``double_integrator`` seeds 0–199: 197/200 with every turn, 200/200
    without the turns onto an obstacle's face).
    """
    heading = goals if navigation is None else navigation.step(estimates, arrived)[0]
    proj = project_onto_cells(heading, cells)
    turn = ~arrived & ~proj.empty & blocked_by_robot(estimates, proj.active, cells, params.face_near)
    if params.right_hand_angle > 0 and turn.any():
        turned = right_hand_goals(estimates, heading, np.deg2rad(params.right_hand_angle))
        turn &= ~on_obstacle_face(project_onto_cells(turned, cells).active, cells)
        heading = np.where(turn[:, None], turned, heading)
    parked_target, moving = parking_targets(estimates, goals, arrived, parking, params, local_box, tolerance)
    return np.where(arrived[:, None], parked_target, heading), moving


def on_obstacle_face(active: np.ndarray, cells) -> np.ndarray:
    """``(N,)``: an active constraint of the projection is an obstacle's face."""
    rows = np.arange(len(active))[:, None]
    return np.any((active >= 0) & (cells.kind[rows, np.maximum(active, 0)] == Kind.OBSTACLE), axis=1)
