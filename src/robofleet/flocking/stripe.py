"""The stripe algorithm (Sec. 5.3 of Gervasi & Prencipe, TR-01-24).

Algorithm 1 with a different ``Sort(A, l, b)``: lexicographic by decreasing distance from
the Y axis, then from l, then from b (the displayed condition of Sec. 5.3). It is applied
to the followers (line 13) and to the slots (line 12).

Stable space (Fig. 13): for the i-th follower g of its semi-space, the stripe parallel to
Y between the lines through its neighbours in the ranking, f (rank i − 1, farther from Y)
and h (rank i + 1, closer); the first follower's stripe is unbounded outwards, the last
one's reaches Y. Since the ranking key is the distance from Y, the stable space is the
set of points whose distance from Y lies between those of h and f (the stripe and its
mirror image). Followers "must take care not to deliberately cross their stable space
boundaries": a straight move is cut where it would leave the stable space (shrunk by
``margin``); no curved moves are needed (the stable space of each side is convex).
Followers on Y (S_0) all have distance 0 from Y, so their stripe is degenerate; they
move as in Algorithm 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .basic import BasicAlgorithm, View, signed_distances


@dataclass(frozen=True)
class StripeAlgorithm(BasicAlgorithm):
    """Sec. 5.3. ``margin``: distance kept from the stable-space boundary."""

    margin: float = 1e-3

    name: ClassVar[str] = "stripe"

    def robot_keys(self, followers: np.ndarray, leader: np.ndarray, bary: np.ndarray,
                   lateral: np.ndarray) -> tuple[np.ndarray, ...]:
        """dist(Y, ·), then dist(L, ·), dist(B, ·), then the basic last-resort tie-break."""
        return (np.abs(lateral), *super().robot_keys(followers, leader, bary, lateral))

    def slot_keys(self, points: np.ndarray, bary: np.ndarray, lateral: np.ndarray) -> tuple[np.ndarray, ...]:
        """dist(Y, ·), then dist(L, ·), dist(B_F, ·), pattern index."""
        return (np.abs(lateral), *super().slot_keys(points, bary, lateral))

    def plan_path(self, view: View, target: np.ndarray) -> np.ndarray:
        """Straight move towards ``target`` cut at the boundary of the stable stripe."""
        if view.my_side == 0:
            return target[None, :].copy()
        lo, hi = stable_band(np.abs(view.lateral), view.order[view.my_side], self.margin)
        lat_target = float(signed_distances(target - view.leader, view.y_axis))
        s = first_exit(float(view.lateral[0]), lat_target, lo, hi)
        return (s * target)[None, :]


def stable_band(key: np.ndarray, order: np.ndarray, margin: float) -> tuple[float, float]:
    """(lower, upper) bounds of the observer's key between its ranking neighbours.

    ``order`` sorts the observer's semi-space by decreasing key; the observer is index 0.
    The bounds are shrunk by ``margin`` but never beyond the observer's own key.
    """
    k = int(np.flatnonzero(order == 0)[0])
    mine = float(key[0])
    upper = float(key[order[k - 1]]) - margin if k > 0 else np.inf
    lower = float(key[order[k + 1]]) + margin if k + 1 < len(order) else 0.0
    return min(lower, mine), max(upper, mine)


def first_exit(f0: float, f1: float, lo: float, hi: float) -> float:
    """Largest s ∈ [0, 1] such that ``lo ≤ |f0 + u (f1 − f0)| ≤ hi`` for all u ∈ [0, s].

    The start is assumed inside the band. Exact: the only places where ``|f|`` can leave
    the band are the crossings f = ±lo, ±hi, checked in order.
    """
    df = f1 - f0
    if df == 0.0:
        return 1.0
    cands = sorted(s for c in (lo, -lo, hi, -hi) if np.isfinite(c) for s in [(c - f0) / df] if 0.0 < s < 1.0)
    for s, nxt in zip(cands, [*cands[1:], 1.0]):
        mid = abs(f0 + 0.5 * (s + nxt) * df)
        if mid < lo or mid > hi:
            return float(s)
    return 1.0
