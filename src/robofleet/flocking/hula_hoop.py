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

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .basic import BasicAlgorithm, View, vector_norm
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
        r1 = vector_norm(target - view.leader)
        if lo <= r1 <= hi:
            closest = distance_to_segment(view.leader, target)
            if closest >= lo:
                return target[None, :].copy()
            return spiral(view.leader, np.zeros(2), target, 1.0)
        r0 = float(radius[0])
        bound = hi if r1 > hi else lo
        stop = (bound - r0) / (r1 - r0) if r1 != r0 else 0.0
        return spiral(view.leader, np.zeros(2), target, float(np.clip(stop, 0.0, 1.0)))


def distance_to_segment(p: np.ndarray, end: np.ndarray) -> float:
    """Distance from point ``p`` to the segment from the origin (the robot) to ``end``."""
    length2 = end[0] * end[0] + end[1] * end[1]
    u = (p[0] * end[0] + p[1] * end[1]) / (length2 if length2 > 0 else 1.0)
    u = min(max(u, 0.0), 1.0)
    return vector_norm(p - u * end)


def spiral(center: np.ndarray, start: np.ndarray, target: np.ndarray, stop: float, points: int = HOOP_PATH_POINTS) -> np.ndarray:
    """Points ``(points, 2)`` of the polar spiral around ``center`` from ``start`` towards ``target``.

    Parameter s runs over ``(0, stop]`` in ``points`` equal steps; radius and angle are
    linear in s. Evaluated point by point with the ``math`` functions, as the compiled
    engine (:mod:`.compiled`) does.
    """
    a, b = start - center, target - center
    r0, r1 = vector_norm(a), vector_norm(b)
    th0 = math.atan2(a[1], a[0])
    dth = (math.atan2(b[1], b[0]) - th0 + math.pi) % (2 * math.pi) - math.pi
    step = stop / points
    out = np.empty((points, 2))
    for k in range(1, points + 1):
        s = k * step if k < points else stop
        r, th = r0 + s * (r1 - r0), th0 + s * dth
        out[k - 1] = center[0] + r * math.cos(th), center[1] + r * math.sin(th)
    if stop >= 1.0:
        out[-1] = target
    return out
