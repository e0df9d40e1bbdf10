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
from functools import cached_property

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
        if self.space.n_obstacles == 0:
            return np.zeros(0, dtype=bool)
        obstacle, other, waiter, lo, hi, offset, profile = self._sides
        active = labels[obstacle] == other
        nxt = progress[waiter] + 1
        inside = (nxt >= lo) & (nxt <= hi)
        top = profile[offset + np.where(inside, nxt - lo, 0)]  # a side's own column when inside (else unused)
        return active & inside & (top >= progress[other])

    def states(self, labels: np.ndarray, progress: np.ndarray,
               blocking: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(waiting, moving, finished)`` boolean masks ``(n,)``; ``a_i(t) = moving[i]``.
        ``blocking``: :meth:`blocking_sides` of these labels and progress, when known."""
        s = self.space
        finished = progress >= s.lengths
        blocked = np.zeros(s.n_robots, dtype=bool)
        blocked[s.side_waiter[self.blocking_sides(labels, progress) if blocking is None else blocking]] = True
        waiting = blocked & ~finished
        return waiting, ~blocked & ~finished, finished

    @cached_property
    def _sides(self) -> tuple[np.ndarray, ...]:
        """The side arrays :meth:`blocking_sides` reads (looked up once per plan)."""
        s = self.space
        return s.side_obstacle, s.side_other, s.side_waiter, s.side_lo, s.side_hi, s.side_offset, s.profile
