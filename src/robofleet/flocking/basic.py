"""Algorithm 1, the basic flocking algorithm (Sec. 4 of Gervasi & Prencipe, TR-01-24).

Line numbers below refer to the listing of Algorithm 1 in the paper.

* Line 1: B := barycenter of the followers (the observer included; the leader excluded,
  as the listing says ``Baricenter(Followers)``).
* Line 2: Y := the line through L and B, oriented B → L. When L = B (within
  ``axis_tolerance``) the follower waits (footnote 3): it moves to its own position.
* Lines 3-5: S_0, S_1, S_2 = followers on Y (``|signed distance| ≤ axis_tolerance``),
  on its left, on its right, in the observer's local sense of left. The paper says
  "exactly on Y"; with floating point and a moving Y an exact test would almost never
  hold, and a follower holding an axis slot would flip between S_1 and S_2 as Y drifts
  between its Looks (we measured the column pattern never converging with 1e-6). The
  default tolerance is 0.5 units (patterns span ~100 units).
* Line 6: F := Final_Positions(ℙ, L, Y): ℙ rotated so that its axis B_P → L lies along
  B → L, translated onto L. Line 7: B_F its barycenter. Lines 8-10: F_0, F_1, F_2. The
  side of a slot is decided in pattern coordinates (a proper rotation keeps sides), so
  it is exact.
* Lines 11-14: Sort: decreasing distance from L, then decreasing distance from B (B_F
  for slots). Last tie-break (the paper leaves it open): for slots the pattern index;
  for robots the observer's local coordinates (x, then y) — only reached on exact ties,
  which have probability zero for generic positions.
* Lines 15-38: the case analysis (ranks, the set H of line 21, the ``|S_1| ≤ |S_2|``
  rule of line 35). With ``ranking = "axis_slot_nearest"`` (beyond the paper, opt-in;
  :meth:`BasicAlgorithm.ranked`) the followers of a semi-space beyond ``|F_s|`` — the
  ones lines 18-28 send to the on-axis slot or across — are, while the on-axis slot is
  free, the ones nearest to that slot instead of the ones nearest to L, and H is sorted
  by the distance to it. The paper's ranking cannot form a pattern whose on-axis slot is
  not the nearest to L (:meth:`.patterns.Pattern.axis_slot_ranked_ahead`); the variant
  forms them. Where an index expression of the listing leaves ``1..|F_j|`` (this
  happens only when ``|S_0| > |F_0|``, e.g. line 36 with ``|S_1| = 0``), it is clamped
  into range; an empty F_j falls back to F_0 then to the other side. Both are our
  documented completions of the listing.

The Compute step (:meth:`BasicAlgorithm.decide`) sees only the local snapshot and the
pattern. Per call the cost is O(m log m) for m followers (sorting), all vectorized; the
slot order (lines 7-12) depends on the pattern only and is computed once
(:meth:`BasicAlgorithm.slot_order`). :mod:`.compiled` runs the same steps in O(m) per
call (ranks counted, not sorted) for ASYNC runs.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np

from .model import Decision, FrameAgreement, Snapshot, apply_matrix, wait_decision
from .patterns import Pattern


@dataclass(frozen=True)
class View:
    """The quantities of lines 1-14 as one follower computes them (local frame).

    ``order[j]`` lists follower indices of S_j sorted by :meth:`BasicAlgorithm.robot_keys`
    (index 0 is the observer); ``slots[j]`` lists pattern indices of F_j sorted likewise.
    """

    followers: np.ndarray
    leader: np.ndarray
    barycenter: np.ndarray
    y_axis: np.ndarray          # unit direction of Y (B → L in Algorithm 1)
    lateral: np.ndarray         # signed distance of each follower to Y, > 0 on the left
    side: np.ndarray            # 0 on Y, 1 left (S_1), 2 right (S_2)
    order: tuple[np.ndarray, np.ndarray, np.ndarray]
    slot_points: np.ndarray     # (m, 2) slot positions in the local frame, indexed by pattern index
    slots: tuple[np.ndarray, np.ndarray, np.ndarray]
    robot_keys: tuple[np.ndarray, ...] = field(repr=False, default=())

    @property
    def my_side(self) -> int:
        return int(self.side[0])

    @property
    def my_rank(self) -> int:
        """1-based rank k of the observer in its S_j (``Rank(me, S_j)``)."""
        return int(np.flatnonzero(self.order[self.my_side] == 0)[0]) + 1


def sort_descending(keys: tuple[np.ndarray, ...]) -> np.ndarray:
    """Indices sorting lexicographically by ``keys`` (primary first), each decreasing."""
    if len(keys[0]) == 0:
        return np.empty(0, dtype=np.intp)
    return np.lexsort(tuple(-k for k in reversed(keys)))


def side_labels(lateral: np.ndarray, tolerance: float) -> np.ndarray:
    """0 on the axis (``|lateral| ≤ tolerance``), 1 on its left, 2 on its right."""
    return np.where(np.abs(lateral) <= tolerance, 0, np.where(lateral > 0, 1, 2))


@dataclass(frozen=True)
class BasicAlgorithm:
    """Algorithm 1 (Sec. 4): oblivious, deterministic, no agreement on local frames.

    Parameters
    ----------
    axis_tolerance:
        Distance (in the common unit) within which a robot counts as lying on Y (S_0)
        and within which L = B counts as the tie of footnote 3.
    ranking:
        ``"paper"`` (lines 12-13 as listed) or ``"axis_slot_nearest"`` (deviation, see
        :meth:`ranked`).
    """

    axis_tolerance: float = 0.5
    ranking: Literal["paper", "axis_slot_nearest"] = "paper"

    name: ClassVar[str] = "basic"
    frames: ClassVar[FrameAgreement] = "none"
    needs_heading: ClassVar[bool] = False
    needs_memory: ClassVar[bool] = False
    path_points: ClassVar[int] = 1

    # ---- Compute --------------------------------------------------------------------
    def decide(self, snapshot: Snapshot, pattern: Pattern, rng: np.random.Generator | None = None) -> Decision:
        """One Compute step (lines 1-38) from the local ``snapshot``; returns the Move."""
        axis = self.y_axis(snapshot)
        if axis is None:
            return wait_decision(self.remember(snapshot))
        pattern_points = self.oriented_pattern(snapshot, pattern, axis, rng)
        if isinstance(pattern_points, Decision):
            return pattern_points
        view = self.view(snapshot, pattern, pattern_points, axis)
        slot = self.choose_slot(view, rng)
        path = self.plan_path(view, view.slot_points[slot])
        return Decision(path, int(slot), self.remember(snapshot))

    # ---- lines 1-2 ------------------------------------------------------------------
    def y_axis(self, snapshot: Snapshot) -> np.ndarray | None:
        """Unit vector of Y = B → L (line 2), ``None`` for the L = B tie (footnote 3)."""
        to_leader = snapshot.leader - barycenter(snapshot.followers)
        norm = vector_norm(to_leader)
        return None if norm <= self.axis_tolerance else to_leader / norm

    def pattern_axis(self, pattern: Pattern) -> np.ndarray:
        """The pattern direction that Final_Positions aligns with Y: B_P → L."""
        return pattern.axis

    def oriented_pattern(self, snapshot: Snapshot, pattern: Pattern, axis: np.ndarray,
                         rng: np.random.Generator | None) -> np.ndarray | Decision:
        """Pattern points to place (the randomized variant may mirror them here)."""
        return pattern.points

    def remember(self, snapshot: Snapshot) -> Any:
        """What to store for the next cycle (nothing: the algorithm is oblivious)."""
        return None

    # ---- lines 3-14 -----------------------------------------------------------------
    def view(self, snapshot: Snapshot, pattern: Pattern, pattern_points: np.ndarray, axis: np.ndarray) -> View:
        """Lines 1-14: B, Y, S_j, F, B_F, F_j and the sorted orders."""
        followers, leader = snapshot.followers, snapshot.leader
        bary = barycenter(followers)
        lateral = signed_distances(followers - leader, axis)
        side = side_labels(lateral, self.axis_tolerance)
        keys = self.robot_keys(followers, leader, bary, lateral)
        order = sort_descending(keys)
        robot_order = tuple(order[side[order] == j] for j in range(3))

        pax = self.pattern_axis(pattern)
        slot_points = apply_matrix(_rotation(pax, axis), pattern_points) + leader          # line 6
        return View(followers, leader, bary, axis, lateral, side, robot_order, slot_points,
                    self.slot_order(pattern, pattern_points), keys)

    def slot_order(self, pattern: Pattern, pattern_points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Lines 7-12: F_0, F_1, F_2 as pattern indices sorted by :meth:`slot_keys`.

        They depend on the pattern points (in pattern coordinates) only, not on the Look,
        so they are computed once per pattern (and mirror image) and reused.
        """
        pax = self.pattern_axis(pattern)
        return _slot_order(self, pattern_points.tobytes(), len(pattern_points), pax.tobytes(), pattern.scale_tolerance)

    def robot_keys(self, followers: np.ndarray, leader: np.ndarray, bary: np.ndarray, lateral: np.ndarray) -> tuple[np.ndarray, ...]:
        """Sort keys of line 13, primary first: dist(L, ·), dist(B, ·), then local x, y."""
        return (np.linalg.norm(followers - leader, axis=1), np.linalg.norm(followers - bary, axis=1), *self.tie_keys(followers, lateral))

    def tie_keys(self, followers: np.ndarray, lateral: np.ndarray) -> tuple[np.ndarray, ...]:
        """Last-resort tie-break: local coordinates (frame dependent; exact ties only)."""
        return (followers[:, 0], followers[:, 1])

    def slot_keys(self, points: np.ndarray, bary: np.ndarray, lateral: np.ndarray) -> tuple[np.ndarray, ...]:
        """Sort keys of line 12 in pattern coordinates (L at the origin): dist(L, ·), dist(B_F, ·), index."""
        return (np.linalg.norm(points, axis=1), np.linalg.norm(points - bary, axis=1), -np.arange(len(points), dtype=float))

    # ---- lines 15-38 ----------------------------------------------------------------
    def choose_slot(self, view: View, rng: np.random.Generator | None) -> int:
        """The case analysis of lines 15-38; returns the pattern index of the target slot."""
        if view.my_side == 0:
            return self._case_s0(view, rng)
        return self._case_side(view, view.my_side, rng)

    def _case_side(self, view: View, s: int, rng) -> int:
        """Lines 16-28 for me ∈ S_s (s = 1; s = 2 is the symmetric case of line 30)."""
        o = 3 - s
        k = int(np.flatnonzero(self.ranked(view, s) == 0)[0]) + 1
        n_fs, n_fo, n_f0 = len(view.slots[s]), len(view.slots[o]), len(view.slots[0])
        n_s0 = len(view.order[0])
        if k <= n_fs:                                                                  # line 18
            return self._pick(view, s, k, s)
        if k <= n_fs + n_f0 - n_s0:                                                    # line 20
            k_prime = self.rank_in_h(view, rng)                                        # lines 21-24
            return self._pick(view, 0, k_prime + n_s0, s)                              # line 25
        return self._pick(view, o, n_fo - (k - n_fs - n_f0 + n_s0) + 1, s)             # line 28

    def _case_s0(self, view: View, rng) -> int:
        """Lines 31-38 for me ∈ S_0."""
        k = view.my_rank
        n_f0 = len(view.slots[0])
        if k <= n_f0:                                                                  # line 34
            return self._pick(view, 0, k, 1)
        side = self.s0_side(view, rng)                                                 # line 35
        return self._pick(view, side, len(view.slots[side]) - len(view.order[side]) + (k - n_f0), side)

    def s0_side(self, view: View, rng: np.random.Generator | None) -> int:
        """Line 35: the side with fewer robots; F_1 when ``|S_1| = |S_2|``."""
        return 1 if len(view.order[1]) <= len(view.order[2]) else 2

    def h_set(self, view: View) -> np.ndarray:
        """Line 21-23: robots of S_1 ranked beyond ``|F_1|`` and of S_2 beyond ``|F_2|``,
        sorted by line 13 (``axis_slot_nearest``: nearest to the on-axis slot first)."""
        extra = [self.ranked(view, j)[len(view.slots[j]):] for j in (1, 2)]
        members = np.concatenate(extra)
        slot = self.open_axis_slot(view)
        if slot is not None:
            return members[np.argsort(np.linalg.norm(view.followers[members] - slot, axis=1), kind="stable")]
        keys = tuple(k[members] for k in view.robot_keys)
        return members[sort_descending(keys)]

    def open_axis_slot(self, view: View) -> np.ndarray | None:
        """The first F_0 slot (local frame) while F_0 has more slots than S_0 robots, with
        ``ranking = "axis_slot_nearest"``; ``None`` otherwise (the paper's ranking applies)."""
        if self.ranking == "paper" or len(view.slots[0]) <= len(view.order[0]):
            return None
        return view.slot_points[view.slots[0][0]]

    def ranked(self, view: View, j: int) -> np.ndarray:
        """S_j in the order its ranks k are counted in (lines 17-28).

        The paper's order (line 13: decreasing distance from L, then from B); with
        ``ranking = "axis_slot_nearest"`` and a free on-axis slot, the ``|S_j| − |F_j|``
        followers nearest to that slot move to the end, nearest first, so that they, not
        the followers nearest to L, are the ones beyond ``|F_j|`` (deviation from the
        paper: near the formation the follower at the on-axis slot keeps it, whatever its
        distance from L). The rest keep the paper's order. Distances to a point of Y
        are the same in every local frame: no common chirality is needed.
        """
        order = view.order[j]
        excess = len(order) - len(view.slots[j])
        slot = self.open_axis_slot(view)
        if slot is None or excess <= 0:
            return order
        nearest = np.argsort(np.linalg.norm(view.followers[order] - slot, axis=1), kind="stable")[:excess]
        rest = np.setdiff1d(np.arange(len(order)), nearest)
        return np.concatenate([order[rest], order[nearest]])

    def rank_in_h(self, view: View, rng: np.random.Generator | None) -> int:
        """Line 24: k' = Rank(me, H) (1-based)."""
        return int(np.flatnonzero(self.h_set(view) == 0)[0]) + 1

    @staticmethod
    def _pick(view: View, j: int, index: int, own_side: int) -> int:
        """The ``index``-th (1-based) slot of F_j, clamped; empty F_j falls back (module doc)."""
        for jj in (j, 0, own_side, 3 - own_side):
            if len(view.slots[jj]):
                return int(view.slots[jj][min(max(index, 1), len(view.slots[jj])) - 1])
        raise AssertionError("a pattern always has at least one slot")

    # ---- Move -----------------------------------------------------------------------
    def plan_path(self, view: View, target: np.ndarray) -> np.ndarray:
        """``Move(p)``: a straight move towards ``p``."""
        return target[None, :].copy()


@functools.lru_cache(maxsize=64)
def _slot_order(algorithm: BasicAlgorithm, points: bytes, n: int, pattern_axis: bytes,
                tolerance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`BasicAlgorithm.slot_order` for the points and axis given as bytes (cache key)."""
    pattern_points = np.frombuffer(points, dtype=float).reshape(n, 2)
    pax = np.frombuffer(pattern_axis, dtype=float)
    p_lateral = pax[0] * pattern_points[:, 1] - pax[1] * pattern_points[:, 0]
    p_side = side_labels(p_lateral, tolerance)                                             # lines 8-10
    p_order = sort_descending(algorithm.slot_keys(pattern_points, barycenter(pattern_points), p_lateral))  # line 12
    slots = tuple(p_order[p_side[p_order] == j] for j in range(3))
    for ranked in slots:
        ranked.setflags(write=False)
    return slots


def barycenter(points: np.ndarray) -> np.ndarray:
    """Mean of ``(n, 2)`` points (line 1, line 7): the correctly rounded sum of each
    coordinate (:func:`math.fsum`) over n. The same whatever the order of the points, so
    it does not depend on how a snapshot lists them."""
    return np.array([math.fsum(points[:, 0].tolist()), math.fsum(points[:, 1].tolist())]) / len(points)


def vector_norm(v: np.ndarray) -> float:
    """Euclidean length of one 2-D vector, as ``sqrt(x x + y y)``."""
    return float(np.sqrt(v[0] * v[0] + v[1] * v[1]))


def signed_distances(offsets: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Signed distance of each offset ``(n, 2)`` from a line of unit direction ``axis``
    through its origin, > 0 on the left: ``offset · (−a_y, a_x)``, written out per term."""
    return offsets[..., 0] * -axis[1] + offsets[..., 1] * axis[0]


def _rotation(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Proper rotation taking unit ``src`` onto unit ``dst``."""
    c = src[0] * dst[0] + src[1] * dst[1]
    s = src[0] * dst[1] - src[1] * dst[0]
    return np.array([[c, -s], [s, c]])
