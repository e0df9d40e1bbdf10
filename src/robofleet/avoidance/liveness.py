"""Liveness for B-UAVC: parked robots that make room (issue 10, item 1).

A robot that has reached its goal holds still in the authors' controllers
(notes/buavc.md "Controllers"), so two robots parked close together can trap a third
one for good: the appendix-C goal rotation never opens a gap that is not there. Here a
parked robot *yields*: when some neighbour's estimate has stayed within ``near`` of its
own estimate for ``linger_steps`` consecutive steps, it steps aside, away from the
lingering neighbours, to a point at most ``aside`` from its goal, for ``yield_steps``
steps, then drives back to its goal for as long again and holds. The idea of arrived
robots yielding is the one the issue's prototype used; the rule, the thresholds and the
hold/yield/return cycle are ours (documented here).

Decentralized and communication-free: a robot uses only its own estimate and goal and
the estimates of the neighbours it sees (those in its local box R_loc); it cannot tell
whether a neighbour has arrived. Every target is projected onto the robot's own cell
(:func:`~robofleet.avoidance.projection.project_onto_cells`), so the command keeps the
next position inside the cell exactly as the normal controller does: the chance
constraint is never traded for liveness.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HOLD, YIELD, RETURN = 0, 1, 2


@dataclass(frozen=True)
class LivenessParams:
    """Parameters of the parked-robot yielding rule (module docstring).

    Attributes
    ----------
    enabled: whether parked robots yield at all (off: they hold, as in the paper).
    near: neighbour distance [m] that counts as lingering near a parked robot.
    linger_steps: consecutive steps a neighbour must linger before the robot yields.
    aside: largest distance [m] from its goal a yielding robot moves to.
    yield_steps: steps spent stepping aside (as many are then spent returning).
    """

    enabled: bool = False
    near: float = 1.0
    linger_steps: int = 30
    aside: float = 0.6
    yield_steps: int = 25


@dataclass
class ParkingState:
    """Per-robot memory of the yielding rule (a robot keeps only its own)."""

    mode: np.ndarray
    mode_left: np.ndarray
    linger: np.ndarray
    target: np.ndarray
    yields: np.ndarray

    @classmethod
    def initial(cls, n: int, dim: int = 2) -> ParkingState:
        return cls(np.zeros(n, np.int8), np.zeros(n, np.int32), np.zeros(n, np.int32), np.zeros((n, dim)), np.zeros(n, np.int64))


def lingering_neighbours(estimates: np.ndarray, near: float, local_box: float = np.inf) -> np.ndarray:
    """``(N, N)`` mask: robot j's estimate lies within ``near`` of robot i's (and in i's
    local box), ``j ≠ i``."""
    diff = estimates[None, :] - estimates[:, None]
    close = (np.linalg.norm(diff, axis=-1) < near) & np.all(np.abs(diff) <= local_box, axis=-1)
    np.fill_diagonal(close, False)
    return close


def aside_points(estimates: np.ndarray, goals: np.ndarray, close: np.ndarray, aside: float) -> np.ndarray:
    """Where each robot steps aside to: its goal moved by ``aside`` along the mean unit
    direction away from its close neighbours (the goal itself when that mean vanishes)."""
    diff = estimates[:, None] - estimates[None, :]
    unit = diff / np.maximum(np.linalg.norm(diff, axis=-1, keepdims=True), 1e-12)
    away = np.sum(np.where(close[..., None], unit, 0.0), axis=1)
    norm = np.linalg.norm(away, axis=1, keepdims=True)
    return goals + aside * np.where(norm > 1e-9, away / np.maximum(norm, 1e-12), 0.0)


def parking_targets(estimates: np.ndarray, goals: np.ndarray, parked: np.ndarray, state: ParkingState,
                    params: LivenessParams, local_box: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
    """Advance the yielding rule one step; return each parked robot's target and which
    parked robots move this step (``(N, 2)``, ``(N,)``; rows of robots not parked are
    their goals and ``False``).

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
    """
    state.mode_left -= state.mode != HOLD
    done = (state.mode != HOLD) & (state.mode_left <= 0)
    back = done & (state.mode == YIELD)
    state.mode[done] = HOLD
    state.mode[back], state.mode_left[back] = RETURN, params.yield_steps
    state.mode[~parked] = HOLD
    close = lingering_neighbours(estimates, params.near, local_box)
    holding = parked & (state.mode == HOLD)
    state.linger = np.where(holding & close.any(axis=1), state.linger + 1, 0)
    start = holding & (state.linger >= params.linger_steps)
    if start.any():
        state.target[start] = aside_points(estimates, goals, close, params.aside)[start]
        state.mode[start], state.mode_left[start], state.linger[start] = YIELD, params.yield_steps, 0
        state.yields += start
    target = np.where((state.mode == YIELD)[:, None], state.target, goals)
    return target, parked & (state.mode != HOLD)
