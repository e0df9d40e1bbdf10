"""Yielding stage: arrived robots step aside for neighbours that wait to pass, and return
(docs/theory/buavc.md "Navigation stages").

The authors' controllers stop a robot for good at its goal, so a robot parked on a goal
in a passage blocks whoever needs that passage. Here a parked robot whose neighbour
lingers within ``near`` steps aside — away from that neighbour and ``aside_turn`` to its
left, the side a right-hand neighbour does not take — stays aside while the neighbour
lingers, returns to its goal when the way is clear, and backs off exponentially.

Rule (per robot, every step; :func:`parking_targets`):

* a neighbour *lingers* when its estimate lies within ``near`` of the robot's and it does
  not hold still (:class:`StillTracker`: within ``still_radius`` of its running mean
  ``m ← m + (2/still_steps)(p̂ − m)`` for ``still_steps`` steps: parked, most likely), nor
  rests (:class:`.progress.ParkedTest`: it has stayed within ``max_aside + still_radius``
  of where it came to rest for ``parked_steps`` steps — a parked robot stepping aside or
  back) farther than ``press`` away;
* HOLD → YIELD once the leaky linger count reaches ``2^k · linger_steps`` after the
  robot's k-th yield; the target is ``g + aside · R(aside_turn) ā`` with ``ā`` the mean
  unit direction away from the lingering neighbours, pulled back to within ``max_aside``
  of the goal;
* YIELD → RETURN after ``clear_steps`` steps with nobody near, or ``max_yield_steps``
  steps aside; RETURN → HOLD when the estimate is within the goal tolerance, or after
  ``return_steps`` steps.

What the stage guarantees: it only chooses targets; the model's cell-keeping controller
keeps every next position inside the cell. The back-off doubles the linger count a robot
needs after each of its yields, so two parked robots that see each other linger yield a
finite number of times per ``2^k`` growth, never in lock-step for ever. A robot uses only
its own estimate and goal and the estimates of the neighbours in its local box R_loc.
Measured effects: docs/results/avoidance.md "Measurements behind the navigation stages".
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

from ..kernels import use_parallel
from .goal import row_distance
from .params import YieldingParams
from .progress import ParkedTest

HOLD, YIELD, RETURN = 0, 1, 2


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
        """Update with this step's estimates (in place, one compiled pass); return the still
        counts ``(N,)``."""
        args = (np.ascontiguousarray(estimates, dtype=np.float64), self.mean, self.still, 2.0 / steps, float(radius))
        if use_parallel(len(estimates)):
            _still_parallel(*args)
        else:
            _still_pass(0, len(estimates), *args)
        return self.still


_CHUNK = 1024  # robots per parallel task


@numba.njit(cache=True, parallel=True)
def _still_parallel(estimates, mean, still, rate, radius):
    n = len(estimates)
    for c in numba.prange((n + _CHUNK - 1) // _CHUNK):
        _still_pass(c * _CHUNK, min(n, (c + 1) * _CHUNK), estimates, mean, still, rate, radius)


@numba.njit(cache=True)
def _still_pass(lo, hi, estimates, mean, still, rate, radius):
    """:meth:`StillTracker.observe` for robots ``lo … hi − 1``, in place: a mean not yet set
    (``mean[i, 0]`` not finite) starts at the estimate; ``m ← m + (p̂ − m) · rate``; the
    still count grows by one while ``‖p̂ − m‖ < radius`` and is 0 otherwise. Rounded as
    the numpy expressions of the rule (:func:`.goal.row_distance` for the norm)."""
    for i in range(lo, hi):
        fresh = not np.isfinite(mean[i, 0])
        for c in range(mean.shape[1]):
            if fresh:
                mean[i, c] = estimates[i, c]
            mean[i, c] += (estimates[i, c] - mean[i, c]) * rate
        still[i] = still[i] + 1 if row_distance(estimates, mean, i) < radius else 0


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
    resting: ParkedTest  # and whether it has stayed near where it came to rest

    def observe(self, estimates: np.ndarray, params: YieldingParams) -> tuple[np.ndarray, np.ndarray]:
        """Update what the neighbours see of each robot and return which robots hold still
        (:class:`StillTracker`: for ``still_steps`` steps) and which stayed where they came
        to rest for ``parked_steps`` steps (:class:`.progress.ParkedTest`)."""
        still = self.stillness.observe(estimates, params.still_radius, params.still_steps) >= params.still_steps
        radius = params.max_aside + params.still_radius
        return still, self.resting.observe(estimates, still, self.stillness.mean, radius, params.parked_steps)

    @classmethod
    def initial(cls, n: int, dim: int = 2) -> ParkingState:
        counters = [np.zeros(n, np.int32) for _ in range(3)]
        return cls(np.zeros(n, np.int8), *counters, np.zeros((n, dim)), np.zeros(n, np.int64), StillTracker.initial(n, dim),
                   ParkedTest.initial(n, dim))


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
                    params: YieldingParams, local_box: float = np.inf, tolerance: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Advance the yielding rule one step; return each parked robot's target and which
    parked robots move this step (``(N, 2)``, ``(N,)``; rows of robots not parked are
    their goals and ``False``; ``goals`` itself while nobody is parked).

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
        :class:`YieldingParams`.
    local_box:
        Half-width R_loc of the box within which a robot sees neighbours.
    tolerance:
        The goal tolerance: a returning robot holds once its estimate is this close.
    """
    still, resting = state.observe(estimates, params)
    if not parked.any():  # what the rule below leaves when nobody is parked: all hold, no counts
        state.mode[:], state.linger[:], state.clear[:] = HOLD, 0, 0
        return goals, np.zeros(len(estimates), bool)
    pairs = close_pairs(estimates, params.near, local_box) if parked.any() else np.zeros((0, 2), np.int64)
    pressing = np.linalg.norm(estimates[pairs[:, 0]] - estimates[pairs[:, 1]], axis=1) <= params.press
    pairs = pairs[~still[pairs[:, 1]] & (pressing | ~resting[pairs[:, 1]])]  # who holds still, or rests away, is not waiting to pass
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
