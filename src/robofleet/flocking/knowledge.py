"""Variants with more common knowledge (Sec. 6 of Gervasi & Prencipe, TR-01-24).

* :class:`ObservableHeadingAlgorithm` (Sec. 6.1): the followers see the leader's heading
  ψ_L and compute the slots of the *directed* target 𝒯^{ψ_L} (Y = the line through L
  along ψ_L) instead of approximating the heading by B → L. No wrong-side formations;
  Δ_r coincides with Δ_e at convergence.
* :class:`MemoryAlgorithm` (Sec. 6.3): each follower stores one position, the leader's
  position at its previous Look, and uses the leader's displacement since then as the
  heading (falls back to B → L on its first cycle or when the leader has not moved).
  To compare two positions observed from different places, the follower expresses them in
  a persistent frame: its axes never change and it knows its own position in that frame
  (odometry, :attr:`Snapshot.odometry`) — our modelling of "storing 1 position".
* :class:`ChiralityAlgorithm` (Sec. 6.2.3): common chirality. Y = B → L, X oriented
  clockwise from it and origin B give every follower the same coordinate system; ties
  of the sorting rule are broken by the side of Y (left first), so non-lb-symmetric
  patterns and patterns with several points on Y can be formed.
* :class:`SharedAxesAlgorithm` (Sec. 6.2.4): common direction and orientation of both
  axes (origins differ). The last-resort tie-break of Algorithm 1 (local coordinates)
  becomes common to all followers, so any tie is broken consistently.

The heading-based variants align the pattern's x axis (the leader's heading) with Y, so
they need a pattern symmetric about its x axis (``Pattern.is_directed`` and lb-symmetric).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .basic import BasicAlgorithm, vector_norm
from .model import FrameAgreement, Snapshot
from .patterns import Pattern

X_AXIS = np.array([1.0, 0.0])
#: Leader displacement (units) below which the stored position gives no heading.
MIN_LEADER_STEP = 1e-9


@dataclass(frozen=True)
class ObservableHeadingAlgorithm(BasicAlgorithm):
    """Sec. 6.1: slots of the directed target from the observed heading."""

    name: ClassVar[str] = "observable_heading"
    needs_heading: ClassVar[bool] = True

    def y_axis(self, snapshot: Snapshot) -> np.ndarray | None:
        """Y = the leader's heading (unit vector in the local frame)."""
        h = snapshot.leader_heading
        return h / vector_norm(h)

    def pattern_axis(self, pattern: Pattern) -> np.ndarray:
        """The pattern's x axis is the leader's direction (Sec. 4.2)."""
        return X_AXIS


@dataclass(frozen=True)
class MemoryAlgorithm(BasicAlgorithm):
    """Sec. 6.3: heading inferred from the leader position stored at the previous Look."""

    name: ClassVar[str] = "memory"
    needs_memory: ClassVar[bool] = True

    def _leader_persistent(self, snapshot: Snapshot) -> np.ndarray:
        return snapshot.odometry + snapshot.leader

    def y_axis(self, snapshot: Snapshot) -> np.ndarray | None:
        """Leader displacement since the stored position; B → L when unavailable."""
        if snapshot.memory is not None:
            step = self._leader_persistent(snapshot) - np.asarray(snapshot.memory)
            norm = vector_norm(step)
            if norm > MIN_LEADER_STEP:
                return step / norm
        return super().y_axis(snapshot)

    def pattern_axis(self, pattern: Pattern) -> np.ndarray:
        return X_AXIS

    def remember(self, snapshot: Snapshot) -> np.ndarray:
        """Store one position: the leader's, in the persistent frame (two reals)."""
        return self._leader_persistent(snapshot)


@dataclass(frozen=True)
class ChiralityAlgorithm(BasicAlgorithm):
    """Sec. 6.2.3: shared chirality gives a shared frame (B, Y = B→L, X clockwise)."""

    name: ClassVar[str] = "chirality"
    frames: ClassVar[FrameAgreement] = "chirality"

    def robot_keys(self, followers: np.ndarray, leader: np.ndarray, bary: np.ndarray,
                   lateral: np.ndarray) -> tuple[np.ndarray, ...]:
        """dist(L, ·), dist(B, ·), then the shared coordinates: side of Y (left first), along Y."""
        to_leader = leader - bary
        unit = to_leader / vector_norm(to_leader)
        offsets = followers - bary
        along = offsets[:, 0] * unit[0] + offsets[:, 1] * unit[1]
        d_l = np.linalg.norm(followers - leader, axis=1)
        d_b = np.linalg.norm(followers - bary, axis=1)
        return (d_l, d_b, lateral, along)


@dataclass(frozen=True)
class SharedAxesAlgorithm(BasicAlgorithm):
    """Sec. 6.2.4: shared axes; the local-coordinate tie-break is common to all."""

    name: ClassVar[str] = "shared_axes"
    frames: ClassVar[FrameAgreement] = "axes"

    def tie_keys(self, followers: np.ndarray, lateral: np.ndarray) -> tuple[np.ndarray, ...]:
        """Shared x then y. Local origins differ, but with common axes a translation does
        not change the order of coordinates, so every follower sorts alike."""
        return (followers[:, 0], followers[:, 1])
