"""The hula-hoop algorithm (Sec. 5.2 of Gervasi & Prencipe, TR-01-24).

Same slot assignment as Algorithm 1 (ranking by distance from L, then from B). What
changes is the Move: the ranking of a follower g in its semi-space does not change while
g stays in its *stable space* (Fig. 12): the annulus centred on the leader L between the
circles through its ranking neighbours h (rank i + 1, closer to L) and f (rank i − 1,
farther); the first follower's annulus is unbounded outwards, the last one's is a disc.
The follower

1. stops before crossing the stable-space boundary when the target is outside it, and
2. follows a curved trajectory when the target is inside but the straight segment
   would cross the boundary (a straight segment between two points of an annulus can
   only leave it through the inner circle).

The curve is the polar spiral around L, ``r(s) = r0 + s (r1 − r0)``,
``θ(s) = θ0 + s Δθ`` (shortest Δθ), sampled with ``path_points`` = 32 waypoints (chords sag inside by at most r(1 − cos(π/64)) ≈ 1.2e-3 r between waypoints): its radius is
monotone, so it stays in the annulus, and when the target is outside, the move stops where
``r`` reaches the boundary (shrunk by ``margin``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..core.geometry import point_segment_distance
from .basic import BasicAlgorithm, View
from .stripe import stable_band

HOOP_PATH_POINTS = 32


@dataclass(frozen=True)
class HulaHoopAlgorithm(BasicAlgorithm):
    """Sec. 5.2. ``margin``: distance kept from the stable-space boundary."""

    margin: float = 1e-3

    name: ClassVar[str] = "hula_hoop"
    path_points: ClassVar[int] = HOOP_PATH_POINTS

    def plan_path(self, view: View, target: np.ndarray) -> np.ndarray:
        """Straight, curved, or stopped at the annulus boundary (module docstring)."""
        radius = np.linalg.norm(view.followers - view.leader, axis=1)
        lo, hi = stable_band(radius, view.order[view.my_side], self.margin)
        r1 = float(np.linalg.norm(target - view.leader))
        if lo <= r1 <= hi:
            closest = float(point_segment_distance(view.leader[None], np.zeros((1, 2)), target[None])[0, 0])
            if closest >= lo:
                return target[None, :].copy()
            return spiral(view.leader, np.zeros(2), target, 1.0)
        r0 = float(radius[0])
        bound = hi if r1 > hi else lo
        stop = (bound - r0) / (r1 - r0) if r1 != r0 else 0.0
        return spiral(view.leader, np.zeros(2), target, float(np.clip(stop, 0.0, 1.0)))


def spiral(center: np.ndarray, start: np.ndarray, target: np.ndarray, stop: float, points: int = HOOP_PATH_POINTS) -> np.ndarray:
    """Points ``(points, 2)`` of the polar spiral around ``center`` from ``start`` towards ``target``.

    Parameter s runs over ``(0, stop]``; radius and angle are linear in s.
    """
    a, b = start - center, target - center
    r0, r1 = np.linalg.norm(a), np.linalg.norm(b)
    th0 = np.arctan2(a[1], a[0])
    dth = (np.arctan2(b[1], b[0]) - th0 + np.pi) % (2 * np.pi) - np.pi
    s = np.linspace(0.0, stop, points + 1)[1:]
    r, th = r0 + s * (r1 - r0), th0 + s * dth
    out = center + np.column_stack([r * np.cos(th), r * np.sin(th)])
    if stop >= 1.0:
        out[-1] = target
    return out
