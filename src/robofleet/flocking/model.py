"""The robot model of Sec. 2: local frames, Look snapshots and Compute decisions.

Each follower has its own local Cartesian frame (Sec. 2): origin at itself, x axis at a
random angle, y axis on a random side (chirality), and the unit of length shared by all
(Observation 3.1). A Look returns a :class:`Snapshot` of the leader and of the other
followers *in that frame*; the Compute step of every algorithm receives only the
snapshot and the pattern, and returns a :class:`Decision` (a path in the same frame).
The scheduler turns the decision back into world coordinates.

The snapshot carries no identities: the other followers are listed in lexicographic
order of their local coordinates, so their order depends on the observer's frame only.
Extra knowledge (Sec. 6) appears only when a variant asks for it: the leader's heading
(Sec. 6.1), the robot's own odometry and one remembered position (Sec. 6.3).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any, Literal, Protocol

import numpy as np

from ..core.rng import RngLike, as_generator
from .patterns import Pattern

FrameAgreement = Literal["none", "chirality", "axes"]


@dataclass(frozen=True)
class LocalFrames:
    """The local frames of ``n`` followers.

    The local coordinates of a world point ``p`` seen from a robot at ``o`` are
    ``M (p − o)`` with ``M = [[cos θ, sin θ], [−h sin θ, h cos θ]]`` (orthogonal).

    Attributes
    ----------
    angle:
        ``(n,)`` angle of each local x axis in the world frame (radians).
    hand:
        ``(n,)`` ``+1`` when the local y axis is the x axis turned counter-clockwise,
        ``-1`` when it is turned clockwise (opposite chirality).
    """

    angle: np.ndarray
    hand: np.ndarray

    @classmethod
    def random(cls, n: int, rng: RngLike = None, agreement: FrameAgreement = "none") -> "LocalFrames":
        """Random frames; ``agreement`` is the common knowledge of Sec. 6.2.

        ``"none"``: random rotation and chirality (Sec. 6.2.1); ``"chirality"``: random
        rotation, common chirality (Sec. 6.2.3); ``"axes"``: common direction and
        orientation of both axes (Sec. 6.2.4; origins still differ).
        """
        gen = as_generator(rng)
        angle = gen.uniform(-np.pi, np.pi, size=n)
        hand = np.where(gen.random(n) < 0.5, -1.0, 1.0)
        if agreement in ("chirality", "axes"):
            hand = np.ones(n)
        if agreement == "axes":
            angle = np.zeros(n)
        return cls(angle.astype(float), hand.astype(float))

    @cached_property
    def matrices(self) -> np.ndarray:
        """``(n, 2, 2)`` world-to-local matrices M_i."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        h = self.hand
        return np.stack([np.stack([c, s], -1), np.stack([-h * s, h * c], -1)], -2)

    def to_local(self, i: int, points: np.ndarray, origin: np.ndarray) -> np.ndarray:
        """World points ``(..., 2)`` in the frame of robot ``i`` placed at ``origin``: M_i (p − o)."""
        return apply_matrix(self.matrices[i], np.asarray(points, dtype=float) - origin)

    def vectors_to_local(self, i: int, vectors: np.ndarray) -> np.ndarray:
        """World direction vectors in the axes of robot ``i`` (no translation)."""
        return apply_matrix(self.matrices[i], np.asarray(vectors, dtype=float))

    def to_world(self, i: int, local: np.ndarray, origin: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`to_local`: M_iᵀ q + o."""
        return apply_matrix(self.matrices[i].T, np.asarray(local, dtype=float)) + origin


def apply_matrix(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``matrix @ p`` for every point ``p`` of ``points`` ``(..., 2)``, as ``a x + b y`` per row.

    Written out (one IEEE product per term, then one sum) rather than as ``points @ matrix.T``:
    a BLAS product fuses some of these multiply-adds and not others depending on the array
    length and the CPU, so the same positions would round differently in a Look of 3 robots
    and of 1,000, and on two machines. The compiled ASYNC engine
    (:mod:`robofleet.flocking.compiled`) evaluates the same expression term by term.
    """
    x, y = points[..., 0], points[..., 1]
    return np.stack([x * matrix[0, 0] + y * matrix[0, 1], x * matrix[1, 0] + y * matrix[1, 1]], axis=-1)


@dataclass(frozen=True)
class Snapshot:
    """What a follower sees at a Look, in its own local frame (it stands at the origin).

    Attributes
    ----------
    leader:
        ``(2,)`` position of the leader.
    others:
        ``(m − 1, 2)`` positions of the other followers, lexicographically sorted.
    leader_heading:
        unit vector of the leader's heading (Sec. 6.1 only), else ``None``.
    odometry:
        the robot's own position in its persistent frame (Sec. 6.3 only), else ``None``.
    memory:
        the one value the robot stored at its previous cycle (Sec. 6.3 only), else ``None``.
    """

    leader: np.ndarray
    others: np.ndarray
    leader_heading: np.ndarray | None = None
    odometry: np.ndarray | None = None
    memory: Any = None

    @property
    def followers(self) -> np.ndarray:
        """All followers, the observing robot (``me``) first at the origin."""
        return np.concatenate([np.zeros((1, 2)), self.others])


@dataclass(frozen=True)
class Decision:
    """The outcome of Compute, in the local frame.

    Attributes
    ----------
    path:
        ``(K, 2)`` waypoints from the robot's position (excluded) to the destination
        (last row). A straight move has ``K = 1``; the hula-hoop variant returns a curve.
    slot:
        index of the pattern point chosen as target, ``-1`` when waiting.
    memory:
        what the robot stores for its next cycle (Sec. 6.3 variant only).
    """

    path: np.ndarray
    slot: int = -1
    memory: Any = None

    @property
    def destination(self) -> np.ndarray:
        return self.path[-1]


def wait_decision(memory: Any = None) -> Decision:
    """Move towards the current position (the footnote-3 wait)."""
    return Decision(np.zeros((1, 2)), -1, memory)


class Algorithm(Protocol):
    """What a flocking algorithm provides to the schedulers.

    ``decide`` is the Compute step: it must use only ``snapshot``, ``pattern`` and (for
    randomized algorithms) ``rng``.
    """

    name: str
    frames: FrameAgreement
    needs_heading: bool
    needs_memory: bool

    def decide(self, snapshot: Snapshot, pattern: Pattern, rng: np.random.Generator | None = None) -> Decision: ...


def look(frames: LocalFrames, i: int, leader: np.ndarray, followers: np.ndarray, *, heading: np.ndarray | None = None,
         odometry_origin: np.ndarray | None = None, memory: Any = None) -> Snapshot:
    """The Look of follower ``i``: world positions → its local :class:`Snapshot`.

    Parameters
    ----------
    frames:
        all local frames; ``i`` selects the observer.
    leader:
        ``(2,)`` world position of the leader.
    followers:
        ``(m, 2)`` world positions of all followers (row ``i`` is the observer).
    heading:
        world unit heading of the leader, given only to Sec. 6.1/6.3 variants.
    odometry_origin:
        world origin of the observer's persistent frame (Sec. 6.3 variant).
    memory:
        the observer's stored value (Sec. 6.3 variant).
    """
    me = followers[i]
    others = np.delete(followers, i, axis=0)
    local_others = frames.to_local(i, others, me)
    order = np.lexsort((local_others[:, 1], local_others[:, 0]))
    snap_heading = None if heading is None else frames.vectors_to_local(i, heading)
    odo = None if odometry_origin is None else frames.to_local(i, me, odometry_origin)
    return Snapshot(frames.to_local(i, leader, me), local_others[order], snap_heading, odo, memory)
