"""Progress checker: which robots are stuck (Zhu et al. 2022, appendix C; docs/theory/buavc.md
"Deadlock heuristic"). The recovery stage (:mod:`.recovery`) acts on what it finds.

A robot that has not arrived is *stuck* when, over the last ``window`` steps, it made
less progress than a threshold. Estimates are noisy, so the test runs over a window, not
a single step. The measure of progress is what the robot knows of its way home:

* :func:`stalled_along_route` (single integrators): the remaining path length ``L_k`` —
  the route's ``‖p̂ − v‖ + D_i(v)``, or ``‖g − p̂‖`` without a route — shrank by less
  than ``progress_fraction · v_max · window · Δt``: ``L_{k−window} − L_k < f v_max W Δt``;
  or the projected target coincides with the estimate. The window restarts when a
  recovery starts, so the recovery's own steps count towards the next window.
* :func:`displacement_stalled` (the other models and the MPC): the net displacement
  ``‖p̂_k − p̂_{k−window}‖`` is at most ``Δp_min``. Appendix C sums the step lengths
  ``Σ‖Δp‖``; with noisy estimates the summed jitter alone exceeds any useful threshold.
* :func:`livelocks` classifies a stuck robot whose commanded speed averaged at least
  ``v_max / 2`` over the window as a livelock (moving without progress), the others as
  deadlocks (held in place); both start the same recovery.

What it guarantees: a robot is flagged at most once per window between recoveries, so a
recovery always has its full length; it flags nothing while ``enabled`` is off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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



def stalled_along_route(to_go: np.ndarray, move_dist: np.ndarray, history: np.ndarray, step: int, driving: np.ndarray,
                        v_max, dt: float, params: DeadlockParams) -> np.ndarray:
    """Record this step's remaining lengths ``to_go`` in the ring ``history`` ``(window, N)``
    and return the ``driving`` robots that are stuck (module docstring); their window
    restarts. ``move_dist`` is how far each projected target lies from its estimate."""
    slot = step % len(history)
    before = history[slot].copy()
    history[slot] = to_go
    if not params.enabled:
        return np.zeros(len(to_go), bool)
    min_progress = params.progress_fraction * v_max * len(history) * dt
    slow = np.isfinite(before) & (before - to_go < min_progress)
    sitting = move_dist < 1e-9  # projected target at the estimate (an empty cell passes inf)
    stuck = (slow | sitting) & driving
    if stuck.any():
        history[:, stuck] = np.nan  # restart the window after a recovery
    return stuck


def displacement_stalled(moved: np.ndarray, progress: float, full: bool) -> np.ndarray:
    """Robots whose net displacement over a full window, ``moved``, is at most ``progress``."""
    return full & (moved <= progress)


def livelocks(stuck: np.ndarray, speed_history: np.ndarray, v_max) -> np.ndarray:
    """The ``stuck`` robots whose commanded speed averaged at least ``v_max / 2`` over the window."""
    return stuck & (speed_history.mean(axis=0) >= 0.5 * v_max)
