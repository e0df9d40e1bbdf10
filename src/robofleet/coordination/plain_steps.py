"""Compiled execution of the *plain* steps of a run (the label-flipping deadlock paper (2021), Eq. 1 and "Problem Statement").

Most steps of an execution change nothing but the progress ``x``: every robot draws its
disturbance, the moving ones advance (``x_i(t + 1) = x_i(t) + a_i(t) δ_i(t)``) and Eq. 1
gives the next step's ``a_i``. A step ``t`` is *plain* when, besides that,

* no robot reaches its goal by the move (no arrival to record),
* no two robots are in contact after the move (no collision to record),
* ``t + 1`` is inside the step budget (the last decision is the settled state),
* the decision at ``t + 1`` has no flip test to make (no blocking side that
  :func:`~.label_flipping.flip_eligible` allows while the method flips), and
* that decision is not a deadlock (Definition 1).

On a plain step :class:`~.plan_execution.PlanExecutor`'s ``move`` and ``decide`` do
nothing else (no event, no statistic, no label change), so :func:`run_plain_steps`
executes runs of plain steps in one compiled loop and stops *before* the first step that
is not plain, which the executor then runs as before. Each quantity is computed with the
same floating-point operations as the numpy code (``u < p`` per robot; squared distances
``dx·dx + dy·dy`` against ``(2r)²``; Eq. 1 as ``top(x_w + 1) ≥ x_a`` on the side
profiles), so the trace is identical. Cost per step: ``O(n² + m)`` for ``n`` robots and
``m`` obstacles, without a Python call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .coordination_space import CoordinationSpace


@dataclass(frozen=True)
class PlainStepRows:
    """Scratch rows one call of :func:`run_plain_steps` fills (``capacity`` steps, ``n`` robots).

    Row ``r`` of a call starting at step ``k``: ``disturbed`` of step ``k + r``, and
    ``progress``/``waiting`` of the state at ``t = k + r + 1``.
    """

    disturbed: np.ndarray
    progress: np.ndarray
    waiting: np.ndarray

    @classmethod
    def empty(cls, capacity: int, n_robots: int) -> PlainStepRows:
        return cls(np.zeros((capacity, n_robots), dtype=bool), np.zeros((capacity, n_robots), dtype=np.intp),
                   np.zeros((capacity, n_robots), dtype=bool))


def space_arrays(space: CoordinationSpace) -> tuple[np.ndarray, ...]:
    """The side arrays Eq. 1 and the flip eligibility read, in :func:`run_plain_steps`' order."""
    return tuple(np.ascontiguousarray(a, dtype=np.intp) for a in (
        space.side_obstacle, space.side_waiter, space.side_other, space.side_lo, space.side_hi, space.side_offset,
        space.profile, space.side_other_lo, space.lengths))


@numba.njit(cache=True)
def _in_contact(positions, plan_lengths, x, reach2):
    """Whether two robots at progress ``x`` are closer than ``2r`` (``‖π_i(x_i) − π_j(x_j)‖² < (2r)²``)."""
    n = len(x)
    for i in range(n):
        ki = min(x[i], plan_lengths[i])
        for j in range(i + 1, n):
            kj = min(x[j], plan_lengths[j])
            dx = positions[i, ki, 0] - positions[j, kj, 0]
            dy = positions[i, ki, 1] - positions[j, kj, 1]
            if dx * dx + dy * dy < reach2:
                return True
    return False


@numba.njit(cache=True)
def _decide_plain(x, labels, tried, flips, sides, blocked):
    """Eq. 1 at progress ``x`` into ``blocked`` ``(n,)``; ``False`` when a flip test is due
    (a blocking side that may be flipped while ``flips``)."""
    side_obstacle, side_waiter, side_other, side_lo, side_hi, side_offset, profile, side_other_lo, lengths = sides
    blocked[:] = False
    for s in range(len(side_waiter)):
        w, a = side_waiter[s], side_other[s]
        nxt = x[w] + 1
        if labels[side_obstacle[s]] != a or nxt < side_lo[s] or nxt > side_hi[s]:
            continue
        if profile[side_offset[s] + nxt - side_lo[s]] < x[a]:
            continue
        blocked[w] = True
        if flips and not tried[side_obstacle[s]] and side_hi[s] != lengths[w] and side_other_lo[s] > 0 and x[a] < side_other_lo[s]:
            return False
    return True


@numba.njit(cache=True)
def run_plain_steps(k, stop, max_steps, uniforms, block_start, x, moving, waiting, labels, tried, flips, probability,
                    positions, plan_lengths, reach2, sides, rows_disturbed, rows_progress, rows_waiting):
    """Execute the plain steps ``k, k + 1, …`` (before ``stop``) in place; return the first step not executed.

    ``x``, ``moving`` and ``waiting`` ``(n,)`` hold the state and Eq. 1's decision at step
    ``k`` and are updated to those of the returned step; ``uniforms[t − block_start]`` are
    the disturbance draws of step ``t`` (``stop`` must not pass the block). The rows
    (see :class:`PlainStepRows`) of the executed steps are written from row 0.
    """
    n = len(x)
    x_new = np.empty_like(x)
    hit = np.empty(n, dtype=np.bool_)
    blocked = np.empty(n, dtype=np.bool_)
    row = 0
    while k < stop and k + 1 < max_steps:
        arrival = False
        for i in range(n):
            hit[i] = uniforms[k - block_start, i] < probability[i, x[i]]
            x_new[i] = x[i] + 1 if moving[i] and not hit[i] else x[i]
            arrival |= x_new[i] != x[i] and x_new[i] >= plan_lengths[i]
        if arrival or _in_contact(positions, plan_lengths, x_new, reach2):
            break
        if not _decide_plain(x_new, labels, tried, flips, sides, blocked):
            break
        any_waiting, any_moving = False, False
        for i in range(n):
            finished = x_new[i] >= sides[8][i]
            any_waiting |= blocked[i] and not finished
            any_moving |= not blocked[i] and not finished
        if any_waiting and not any_moving:  # a deadlock: the executor records it
            break
        for i in range(n):
            finished = x_new[i] >= sides[8][i]
            x[i] = x_new[i]
            waiting[i] = blocked[i] and not finished
            moving[i] = not blocked[i] and not finished
            rows_disturbed[row, i] = hit[i]
            rows_progress[row, i] = x[i]
            rows_waiting[row, i] = waiting[i]
        row += 1
        k += 1
    return k
