"""Progress checker: which robots are stuck (Zhu et al. 2022, appendix C; docs/theory/buavc.md
"Deadlock heuristic"), one checker shared by the single integrators' navigation pipeline
and the safety filter. The recovery stage (:mod:`.recovery`) acts on what it finds.

**Measure.** Progress is the decrease of the *distance left* ``L`` over the last
``window`` steps. What ``L`` is depends only on what the user of the checker knows of the
way: the route's remaining path length ``‖p̂ − v‖ + D_i(v)`` (or ``‖g − p̂‖`` without a
route) in the navigation pipeline; in the safety filter, which knows no
goal, the motion asked for is the way, and each step ``L`` shrinks by the motion made
along the asked direction. A robot the caller marks as *driving* (not arrived, not
recovering; in the filter: it asked for at least the threshold's motion over the window)
is **stuck** when

* it made less than ``progress_fraction · v_max · window · Δt`` of progress:
  ``L_{k−W} − L_k < f v_max W Δt``; or
* it *sits*: it asked to move and its cell-keeping controller returned no motion in a
  non-empty cell (the projected target lies at the estimate).

Appendix C sums the step lengths ``Σ‖Δp‖``; with noisy estimates the summed jitter alone
exceeds any useful threshold, whereas the jitter of ``L`` cancels over the window.
:meth:`ProgressChecker.livelocks` classes a stuck robot whose commanded speed averaged
at least ``v_max / 2`` over the window as a livelock (moving without progress), the others
as deadlocks (held in place); both start the same recovery.

**What it detects and guarantees.** A driving robot that has not shortened its distance
left by the threshold over a full window is flagged at that step; a robot whose ``L``
shrinks by at least the threshold over every window, and that never sits, is never flagged
(the test is exact on the recorded values, no noise model enters). A flagged robot's
window restarts (the values before it are dropped), so its progress test cannot fire again
within ``window`` steps; a window that is not full (the first ``window`` steps, or after
a restart) flags only sitting robots; nothing is flagged while ``enabled`` is off. The
pipeline does not mark recovering robots as driving, so a recovery runs its full length.

Double integrators, unicycles and the MPC keep appendix C's net displacement
``‖p̂_k − p̂_{k−W}‖ ≤ Δp_min`` as the authors' release measures it
(:class:`.recovery.GoalRotation`): on the path length left, a unicycle turning in place
reads as stuck and the rotated goal turns it further, and double integrators took longer
(docs/results/avoidance.md, "Measurements behind the navigation stages").
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .goal import row_distance


@dataclass(frozen=True)
class DeadlockParams:
    """The recovery stage's parameter block, with the progress window that triggers it
    (appendix C; the scenario's ``deadlock:`` block).

    Attributes
    ----------
    enabled: whether stuck robots are detected and recover.
    window: steps over which progress is measured.
    progress_fraction: a robot is stuck when it made less than this fraction of
        ``v_max · window · Δt`` over the window.
    recover_steps: steps one rotation lasts.
    """

    enabled: bool = True
    window: int = 20
    progress_fraction: float = 0.25
    recover_steps: int = 10



class ProgressChecker:
    """The progress window of one team or filter (module docstring), vectorized over robots.

    ``left`` ``(window, N)`` is the ring of distances left (NaN: not yet recorded, or the
    window restarted), ``speed`` ``(window, N)`` the ring of commanded speeds,
    ``deadlocks`` / ``livelock_count`` the firings so far."""

    def __init__(self, params: DeadlockParams, n: int, v_max, dt: float):
        window = max(params.window, 1)
        self.params, self.v_max, self.dt = params, v_max, dt
        self.left, self.speed = np.full((window, n), np.nan), np.zeros((window, n))
        self.step = 0
        self.deadlocks, self.livelock_count = np.zeros(n, np.int64), np.zeros(n, np.int64)

    @property
    def threshold(self):
        """The least progress over a full window, ``f · v_max · W · Δt``."""
        return self.params.progress_fraction * self.v_max * len(self.left) * self.dt

    def record_speed(self, speed: np.ndarray) -> None:
        """This step's commanded speeds (for :meth:`livelocks`)."""
        self.speed[self.step % len(self.speed)] = speed

    def observe(self, left: np.ndarray, driving: np.ndarray, sitting: np.ndarray | None = None) -> np.ndarray:
        """Record this step's distances left and return the ``driving`` robots that are stuck
        (module docstring); their window restarts and their firing is counted."""
        slot = self.step % len(self.left)
        before = self.left[slot].copy()
        self.left[slot] = left
        self.step += 1
        if not self.params.enabled:
            return np.zeros(len(left), bool)
        slow = np.isfinite(before) & (before - left < self.threshold)
        stuck = (slow if sitting is None else slow | sitting) & driving
        if stuck.any():
            self.left[:, stuck] = np.nan  # restart the window after a recovery
            self.deadlocks += stuck
            self.livelock_count += self.livelocks(stuck)
        return stuck

    def livelocks(self, stuck: np.ndarray) -> np.ndarray:
        """The ``stuck`` robots whose commanded speed averaged at least ``v_max / 2`` over the window."""
        return stuck & (self.speed.mean(axis=0) >= 0.5 * self.v_max)


@dataclass
class ParkedTest:
    """Which robots look *parked* to their neighbours, from their estimates alone: the
    progress test applied from outside, over a long window and with a wide radius.

    A robot's estimate comes to rest when the still test of the yielding stage holds
    (:class:`.yielding.StillTracker`); its running mean then becomes its *anchor*. While
    its estimate stays within ``radius`` of the anchor it has made no progress anywhere,
    and after ``steps`` such steps it counts as parked; it stops counting (and loses its
    anchor) at the first estimate farther than ``radius`` from the anchor.

    What it detects: a robot parked on its goal whose yields and returns (at most
    ``max_aside`` from the goal) or jittering estimates move it about, which the still test
    alone reads as a robot waiting to pass. What it guarantees: a robot is called parked
    only after ``steps`` consecutive steps within ``radius`` of one point where it had come
    to rest, so a robot on its way, or a blocked robot for the first ``steps`` steps after
    it came to rest, is never called parked by this test; ``steps = 0`` switches it off.
    """

    anchor: np.ndarray
    since: np.ndarray

    @classmethod
    def initial(cls, n: int, dim: int = 2) -> ParkedTest:
        return cls(np.full((n, dim), np.nan), np.zeros(n, np.int64))

    def observe(self, estimates: np.ndarray, rest: np.ndarray, mean: np.ndarray, radius: float, steps: int) -> np.ndarray:
        """Update with this step's estimates (``rest``: the still test holds; ``mean``:
        the running means) and return which robots count as parked ``(N,)``."""
        parked = np.zeros(len(estimates), np.bool_)
        if steps > 0:
            _parked_pass(np.ascontiguousarray(estimates, dtype=np.float64), np.ascontiguousarray(rest, dtype=np.bool_),
                         np.ascontiguousarray(mean, dtype=np.float64), self.anchor, self.since, float(radius), int(steps), parked)
        return parked


@numba.njit(cache=True)
def _parked_pass(estimates, rest, mean, anchor, since, radius, steps, parked):
    """:meth:`ParkedTest.observe` for every robot, in place on ``anchor`` and ``since``: a
    robot without an anchor (``anchor[i, 0]`` not finite) that comes to rest anchors at its
    running mean; an anchored robot whose estimate lies farther than ``radius`` from the
    anchor loses it; ``since`` counts the steps anchored (0 without an anchor), and the
    robot counts as parked once ``since ≥ steps``. The distance is :func:`.goal.row_distance`,
    rounded as ``np.linalg.norm``."""
    for i in range(len(estimates)):
        anchored = np.isfinite(anchor[i, 0])
        if rest[i] and not anchored:
            for c in range(anchor.shape[1]):
                anchor[i, c] = mean[i, c]
            anchored = True
        if anchored and row_distance(estimates, anchor, i) > radius:
            for c in range(anchor.shape[1]):
                anchor[i, c] = np.nan
            anchored = False
        since[i] = since[i] + 1 if anchored else 0
        parked[i] = since[i] >= steps
