"""RMTRACK's action rule (the label-flipping deadlock paper (2021), Eq. 1; Čáp, Gregoire & Frazzoli 2016).

Robot ``i`` waits at step ``t`` if some obstacle ``o_ij`` with label ``j`` meets the line
``{x_i(t) + 1} × {x_j(t), …, K_j}``; it is finished at ``x_i = K_i``; otherwise it moves.
Along one column of ``o_ij`` the line test reduces to ``top(x_i + 1) ≥ x_j`` with ``top`` the
column's highest cell, so the rule for all robots is a gather over the flat side profiles
of :class:`~.coordination_space.CoordinationSpace`, ``O(m)`` numpy work per step for
``m`` obstacles and no loop over robots.

Safety in discrete steps with simultaneous moves: while ``ℓ(o) = j`` the invariant
"every column ``k ≤ x_i`` of ``o`` lies below ``x_j``" holds (Eq. 1 checks it before
``i`` enters a column, ``x_j`` only grows), so ``(x_i, x_j)`` never lies in ``o``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .coordination_space import CoordinationSpace


@dataclass(frozen=True)
class ActionRule:
    """Eq. 1 evaluated for all robots at once.

    The returned masks describe the three states of Eq. 1: ``waiting`` (first case),
    ``finished`` (second case), ``moving`` (third case).
    """

    space: CoordinationSpace

    def blocking_sides(self, labels: np.ndarray, progress: np.ndarray) -> np.ndarray:
        """Boolean ``(2m,)``: sides whose obstacle stops their waiter now (first case of Eq. 1)."""
        s = self.space
        if s.n_obstacles == 0:
            return np.zeros(0, dtype=bool)
        active = labels[s.side_obstacle] == s.side_other
        nxt = progress[s.side_waiter] + 1
        inside = (nxt >= s.side_lo) & (nxt <= s.side_hi)
        top = s.profile[s.side_offset + np.clip(nxt - s.side_lo, 0, s.side_hi - s.side_lo)]
        return active & inside & (top >= progress[s.side_other])

    def states(self, labels: np.ndarray, progress: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(waiting, moving, finished)`` boolean masks ``(n,)``; ``a_i(t) = moving[i]``."""
        s = self.space
        finished = progress >= s.lengths
        blocked = np.zeros(s.n_robots, dtype=bool)
        blocked[s.side_waiter[self.blocking_sides(labels, progress)]] = True
        waiting = blocked & ~finished
        return waiting, ~blocked & ~finished, finished
