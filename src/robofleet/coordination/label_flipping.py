"""Label flipping: RMTRACK+TFF and RMTRACK+TFA (Coskun & O'Kane 2019, as summarised in the label-flipping deadlock paper (2021)).

When robot ``w`` waits for an obstacle ``o`` labelled ``a`` (first case of Eq. 1), a flip
test predicts from expected travel times whether ``ℓ(o) := w`` reduces the pair's travel
time.

Expected travel time
    ``E[T_r(k → k')] = Σ_{m=k}^{k'-1} Δ / (1 − p(π_r(m)))``: a geometric number of tries per
    step with the disturbance probability ``p`` at the robot's position. ``p`` is either the
    known region probability (:class:`KnownProbabilities`) or an online estimate from the
    disturbances observed so far (:class:`LearnedProbabilities`).
TFF
    flip iff ``E[T_w(x_w → R_w + 1)] < E[T_a(x_a → B_a)]`` — ``w`` clears ``o`` before ``a``
    even reaches it.
TFA
    roll the pair out around ``o`` in expectation once with each label; flip iff
    ``W_w(w) + W_a(w) < W_w(a) + W_a(a)``, ``W_r(ℓ)`` the expected time until ``r`` clears ``o``.
When a flip is tried
    only for a waiting robot, at most once per obstacle, not when ``o`` reaches ``w``'s goal
    (``R_w = K_w``: ``w`` would park inside it) and only while ``a`` has not reached ``o``
    (``x_a < B_a``). The last condition is also what makes a flip safe: the new label's
    invariant "every row ``k ≤ x_a`` of ``o`` lies left of ``x_w``" then holds trivially.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np

from .coordination_space import CoordinationSpace

TFA_PROBABILITY_CLIP = (0.05, 0.95)


@dataclass
class KnownProbabilities:
    """Disturbance probabilities known from the map: ``p[i, k] = p(π_i(k))``, shape ``(n, K_max + 1)``."""

    probability: np.ndarray
    dt: float
    _cumulative: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        steps = self.dt / (1.0 - self.probability)
        self._cumulative = np.concatenate([np.zeros((len(steps), 1)), np.cumsum(steps, axis=1)], axis=1)

    def expected_time(self, robot: int, start: int, stop: int) -> float:
        """``E[T(start → stop)]`` in seconds (0 when ``stop <= start``)."""
        k = self._cumulative.shape[1] - 1
        a, b = min(start, k), min(max(stop, start), k)
        return float(self._cumulative[robot, b] - self._cumulative[robot, a])

    def probabilities(self, robot: int, start: int, stop: int) -> np.ndarray:
        return self.probability[robot, start:stop]

    def observe(self, cells_or_positions: np.ndarray, attempted: np.ndarray, disturbed: np.ndarray) -> None:
        """Known probabilities do not learn."""


@dataclass
class LearnedProbabilities:
    """Online estimate of the disturbance probability on a square grid over the map.

    Each cell keeps a Beta prior (mean ``prior``, weight ``strength`` observations) updated
    with the observed outcome of every attempted step: ``p̂ = (d + s·p₀) / (n + s)``.
    (The authors' release fitted a Gaussian process to the same frequencies; a per-cell
    Beta estimate is the simple, vectorized stand-in.)

    Parameters
    ----------
    cell_of_step:
        ``(n, K_max + 1)`` grid cell index of ``π_i(k)``.
    n_cells:
        number of grid cells.
    """

    cell_of_step: np.ndarray
    n_cells: int
    dt: float
    prior: float = 0.05
    strength: float = 4.0
    _disturbed: np.ndarray = field(init=False, repr=False)
    _tries: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        self._disturbed = np.zeros(self.n_cells)
        self._tries = np.zeros(self.n_cells)

    def estimate(self) -> np.ndarray:
        return (self._disturbed + self.strength * self.prior) / (self._tries + self.strength)

    def probabilities(self, robot: int, start: int, stop: int) -> np.ndarray:
        return self.estimate()[self.cell_of_step[robot, start:stop]]

    def expected_time(self, robot: int, start: int, stop: int) -> float:
        p = self.probabilities(robot, start, max(stop, start))
        return float(np.sum(self.dt / (1.0 - p)))

    def observe(self, cells: np.ndarray, attempted: np.ndarray, disturbed: np.ndarray) -> None:
        """Record the outcome of this step's attempts (``cells`` of the robots' positions)."""
        np.add.at(self._tries, cells[attempted], 1.0)
        np.add.at(self._disturbed, cells[attempted & disturbed], 1.0)


@dataclass(frozen=True)
class FlipContext:
    """What a flip test sees: robot ``waiter`` stopped by ``side`` (obstacle labelled ``other``)."""

    space: CoordinationSpace
    side: int
    waiter: int
    other: int
    progress: np.ndarray
    times: KnownProbabilities | LearnedProbabilities
    labels: np.ndarray | None = None


def flip_eligible(space: CoordinationSpace, side: int, progress: np.ndarray, tried: np.ndarray) -> bool:
    """Whether a flip of the side's obstacle may be tried (release rules; safe by construction)."""
    w, a = int(space.side_waiter[side]), int(space.side_other[side])
    obstacle = side // 2
    return bool(
        not tried[obstacle]
        and space.side_hi[side] != space.lengths[w]
        and space.side_other_lo[side] > 0
        and progress[a] < space.side_other_lo[side]
    )


def tff_wants_flip(ctx: FlipContext) -> bool:
    """TFF: ``E[T_w(x_w → R_w + 1)] < E[T_a(x_a → B_a)]``."""
    s, x = ctx.space, ctx.progress
    clear_w = ctx.times.expected_time(ctx.waiter, int(x[ctx.waiter]), int(s.side_hi[ctx.side]) + 1)
    reach_a = ctx.times.expected_time(ctx.other, int(x[ctx.other]), int(s.side_other_lo[ctx.side]))
    return clear_w < reach_a


def tfa_wants_flip(ctx: FlipContext) -> bool:
    """TFA: compare the pair's expected clearing times with the current and the flipped label."""
    keep = sum(pair_rollout(ctx, first=ctx.other))
    flip = sum(pair_rollout(ctx, first=ctx.waiter))
    return flip < keep


def pair_rollout(ctx: FlipContext, first: int) -> tuple[float, float]:
    """Expected times ``(W_w, W_a)`` until the waiter and the other robot clear the obstacle.

    Deterministic rollout of the two robots alone around the obstacle, with ``first``
    as label: the robot whose next step completes first (expected step time
    ``Δ / (1 − p)``, ``p`` clipped to [0.05, 0.95]) advances; a blocked robot's clock
    catches up with the other's when it is released. ``O(length of the obstacle)``,
    compiled (:func:`_rollout`).
    """
    s, side = ctx.space, ctx.side
    x_w, x_a = int(ctx.progress[ctx.waiter]), int(ctx.progress[ctx.other])
    target_w, target_a = int(s.side_hi[side]) + 1, int(s.side_hi[side ^ 1]) + 1
    wait_w = side if first == ctx.other else -1  # the side that stops the robot without priority
    wait_a = side ^ 1 if first == ctx.waiter else -1
    return _rollout(_step_times(ctx, ctx.waiter, x_w, target_w), _step_times(ctx, ctx.other, x_a, target_a), x_w, x_a,
                    target_w, target_a, wait_w, wait_a, s.side_lo, s.side_hi, s.side_offset, s.profile)


@numba.njit(cache=True)
def _rollout(step_w, step_a, x_w, x_a, target_w, target_a, wait_w, wait_a, side_lo, side_hi, side_offset, profile):
    """The loop of :func:`pair_rollout` for robots ``0`` (waiter) and ``1`` (other): each
    iteration advances the movable robot whose next step ends first (robot 0 on a tie)."""
    steps = (step_w, step_a)
    start = (x_w, x_a)
    x = np.array([x_w, x_a])
    target = (target_w, target_a)
    wait = (wait_w, wait_a)
    clock, finish = np.zeros(2), np.zeros(2)
    done = np.array([x_w >= target_w, x_a >= target_a])
    blocked = np.zeros(2, dtype=np.bool_)
    while not (done[0] and done[1]):
        for r in range(2):
            blocked[r] = _blocked(side_lo, side_hi, side_offset, profile, wait[r], x[r], x[1 - r])
        movable0, movable1 = not done[0] and not blocked[0], not done[1] and not blocked[1]
        if not movable0 and not movable1:
            return np.inf, np.inf
        if movable0 and movable1:
            r = 1 if clock[1] + steps[1][x[1] - start[1]] < clock[0] + steps[0][x[0] - start[0]] else 0
        else:
            r = 0 if movable0 else 1
        clock[r] += steps[r][x[r] - start[r]]
        x[r] += 1
        if blocked[1 - r]:
            clock[1 - r] = max(clock[1 - r], clock[r])
        if x[r] >= target[r]:
            done[r], finish[r] = True, clock[r]
    return finish[0], finish[1]


def _step_times(ctx: FlipContext, robot: int, start: int, stop: int) -> np.ndarray:
    p = np.clip(ctx.times.probabilities(robot, start, max(stop, start)), *TFA_PROBABILITY_CLIP)
    if len(p) < stop - start:  # beyond the padded plan: the goal's probability
        p = np.concatenate([p, np.full(stop - start - len(p), p[-1] if len(p) else TFA_PROBABILITY_CLIP[0])])
    return ctx.times.dt / (1.0 - p)


@numba.njit(cache=True)
def _blocked(side_lo, side_hi, side_offset, profile, side, own, other):
    """Eq. 1 for one side of one obstacle (``side < 0``: this robot has priority)."""
    if side < 0:
        return False
    nxt = own + 1
    if nxt < side_lo[side] or nxt > side_hi[side]:
        return False
    return profile[side_offset[side] + nxt - side_lo[side]] >= other
