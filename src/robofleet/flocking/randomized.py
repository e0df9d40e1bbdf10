"""Randomized tie breaking (Sec. 6.4 of Gervasi & Prencipe, TR-01-24).

Two modifications of Algorithm 1 ("randomly choosing the target slot among the possible
candidates in steps 29 and 40", i.e. the two tie points of the listing):

* case a (Fig. 14a): a follower on Y (S_0) beyond the F_0 slots chooses F_1 or F_2
  with probability 1/2 when ``|S_1| = |S_2|`` (line 35 would always pick the local F_1);
* case b (Fig. 14b): followers of H ranked equal (symmetric w.r.t. Y: same distance from
  L and from B, within ``tie_tolerance``) choose uniformly among the F_0 slots of their
  tie group (line 24-25 would rank them by a frame-dependent detail).

Non-lb-symmetric patterns (the five steps of Sec. 6.4): the semi-patterns (pattern points
left/right of its L–B_P axis) and the semi-spaces (S_1, S_2) are ranked with the same
metric, and the first semi-space receives the first semi-pattern (the pattern is mirrored
across Y in the local frame when needed); then Algorithm 1 proceeds. The metric is the
paper's *Ranking* procedure (:func:`ranking`); it needs ``|C| = |D|``, so sets of different
sizes are ranked by size first (larger first) — our completion. When the semi-spaces rank
equal (every follower symmetric to another w.r.t. Y), the follower moves towards a random
point within ``random_move`` of itself to break the tie.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .basic import BasicAlgorithm, View, barycenter, side_labels, signed_distances, sort_descending
from .model import Decision, Snapshot
from .patterns import Pattern


def ranking(c: np.ndarray, d: np.ndarray, leader: np.ndarray, bary: np.ndarray, tolerance: float = 0.0) -> int:
    """The *Ranking* procedure of Sec. 6.4: +1 if C ranks higher than D, 0 if equal, −1 otherwise.

    Both sets are sorted with Algorithm 1's ``Sort(·, L, B)`` (decreasing distance from L,
    then from B) and compared element by element on (dist(·, L), dist(·, B)). Distances
    closer than ``tolerance`` count as equal. Sets of different sizes: the larger ranks
    higher (completion for ``|C| ≠ |D|``).
    """
    if len(c) != len(d):
        return 1 if len(c) > len(d) else -1
    kc = _sorted_keys(c, leader, bary)
    kd = _sorted_keys(d, leader, bary)
    for (cl, cb), (dl, db) in zip(kc, kd):
        for x, y in ((cl, dl), (cb, db)):
            if x > y + tolerance:
                return 1
            if x < y - tolerance:
                return -1
    return 0


def _sorted_keys(points: np.ndarray, leader: np.ndarray, bary: np.ndarray) -> np.ndarray:
    keys = (np.linalg.norm(points - leader, axis=1), np.linalg.norm(points - bary, axis=1))
    order = sort_descending(keys)
    return np.column_stack(keys)[order]


@dataclass(frozen=True)
class RandomizedAlgorithm(BasicAlgorithm):
    """Sec. 6.4: Algorithm 1 with random choices at its two tie points; any pattern.

    Parameters
    ----------
    tie_tolerance:
        relative tolerance (× max(1, distance)) for "ranked equal".
    random_move:
        radius of the random tie-breaking move (semi-spaces ranked equal).
    """

    tie_tolerance: float = 1e-9
    random_move: float = 1.0

    name: ClassVar[str] = "randomized"

    def s0_side(self, view: View, rng: np.random.Generator) -> int:
        """Case a: a fair coin when ``|S_1| = |S_2|``, else the side with fewer robots."""
        n1, n2 = len(view.order[1]), len(view.order[2])
        if n1 == n2:
            return int(rng.integers(1, 3))
        return 1 if n1 < n2 else 2

    def rank_in_h(self, view: View, rng: np.random.Generator) -> int:
        """Case b: a uniformly random rank among the followers of H tied with me."""
        h = self.h_set(view)
        dl = view.robot_keys[0][h]
        db = view.robot_keys[1][h]
        me = int(np.flatnonzero(h == 0)[0])
        tol = self.tie_tolerance * max(1.0, float(dl[me]))
        tied = np.flatnonzero((np.abs(dl - dl[me]) <= tol) & (np.abs(db - db[me]) <= tol))
        return int(rng.choice(tied)) + 1 if len(tied) > 1 else me + 1

    def oriented_pattern(self, snapshot: Snapshot, pattern: Pattern, axis: np.ndarray,
                         rng: np.random.Generator) -> np.ndarray | Decision:
        """Steps 1-3 of Sec. 6.4 for non-lb-symmetric patterns; lb-symmetric ones are used as is."""
        if pattern.is_lb_symmetric:
            return pattern.points
        followers, leader = snapshot.followers, snapshot.leader
        bary = barycenter(followers)
        lateral = signed_distances(followers - leader, axis)
        side = side_labels(lateral, self.axis_tolerance)
        tol = self.tie_tolerance * max(1.0, float(np.abs(followers - leader).max()))
        space = ranking(followers[side == 1], followers[side == 2], leader, bary, tol)         # step 2
        if space == 0:
            angle = rng.uniform(-np.pi, np.pi)
            radius = self.random_move * np.sqrt(rng.uniform())
            return Decision(np.array([[radius * np.cos(angle), radius * np.sin(angle)]]), -1, None)
        p_side = pattern.side
        semi = ranking(pattern.points[p_side == 1], pattern.points[p_side == -1], np.zeros(2), pattern.barycenter,
                       pattern.scale_tolerance)                                                # step 1
        return pattern.points if semi == space else pattern.mirrored()                         # step 3
