"""The plan conditions of the theory (the label-flipping deadlock paper (2021), Definition 4 and Theorem 4), evaluated on a plan.

:func:`check_theory` gives Definition 4 (non-conflicting trajectories) and Theorem 4's
precondition (disjoint collision segments) with their violations; :mod:`robofleet.coordination.guarantees`
turns them into what ``robofleet check`` prints, and each planned instance keeps its
report (:attr:`robofleet.coordination.instance.Instance.theory`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..core import arguments
from .coordination_space import CoordinationSpace
from .trajectories import Trajectories


@dataclass(frozen=True)
class Conflict:
    """Robot ``robot`` at its step ``step`` is closer than ``2r`` to the ``which`` of ``other``."""

    robot: int
    step: int
    other: int
    which: str  # "start" or "goal"


@dataclass(frozen=True)
class Overlap:
    """Two collision segments of ``robot`` that share steps (or touch)."""

    robot: int
    first: tuple[int, int]
    second: tuple[int, int]
    others: tuple[int, int]


@dataclass(frozen=True)
class TheoryReport:
    """Outcome of :func:`check_theory`."""

    non_conflicting: bool
    disjoint_segments: bool
    conflicts: list[Conflict] = field(default_factory=list)
    overlaps: list[Overlap] = field(default_factory=list)


def conflicts(traj: Trajectories, limit: int | None = None) -> list[Conflict]:
    """Violations of Definition 4, the first step per (robot, other, start/goal).

    ``O(N log N)`` with a k-d tree over all ``N`` trajectory points.
    """
    n = traj.n_robots
    k = np.arange(traj.positions.shape[1])
    valid = k[None, :] <= traj.lengths[:, None]
    robot_of = np.broadcast_to(np.arange(n)[:, None], valid.shape)[valid]
    step_of = np.broadcast_to(k[None, :], valid.shape)[valid]
    tree = cKDTree(traj.positions[valid])
    out: list[Conflict] = []
    for which, points in (("start", traj.starts), ("goal", traj.goals)):
        for other, hits in enumerate(tree.query_ball_point(points, 2 * traj.radius * (1 - 1e-12))):
            hits = np.asarray(hits, dtype=np.intp)
            hits = hits[robot_of[hits] != other]
            for r in np.unique(robot_of[hits]).tolist():
                mine = hits[robot_of[hits] == r]
                out.append(Conflict(int(r), int(step_of[mine].min()), other, which))
    out.sort(key=lambda c: (c.robot, c.step, c.other))
    return out[:limit] if limit else out


def segment_overlaps(space: CoordinationSpace, limit: int | None = None) -> list[Overlap]:
    """Pairs of collision segments of one robot with ``f(c) ≥ s(c')`` (Theorem 4's condition fails)."""
    out: list[Overlap] = []
    for robot in range(space.n_robots):
        sides = np.flatnonzero(space.side_waiter == robot)
        if len(sides) < 2:
            continue
        order = sides[np.argsort(space.side_lo[sides], kind="stable")]
        lo, hi = space.side_lo[order], space.side_hi[order]
        reach = np.maximum.accumulate(hi)
        bad = np.flatnonzero(lo[1:] <= reach[:-1] + 1)
        for b in bad.tolist():
            prev = int(np.argmax(hi[: b + 1] == reach[b]))
            out.append(Overlap(robot, (int(lo[prev]), int(hi[prev])), (int(lo[b + 1]), int(hi[b + 1])),
                               (int(space.side_other[order[prev]]), int(space.side_other[order[b + 1]]))))
    return out[:limit] if limit else out


def check_theory(traj: Trajectories, space: CoordinationSpace) -> TheoryReport:
    """Definition 4 and Theorem 4's precondition for a plan."""
    arguments.instance(traj, Trajectories, "traj", "a Trajectories plan")  # input validation
    arguments.instance(space, CoordinationSpace, "space", "its CoordinationSpace (build_coordination_space)")
    c = conflicts(traj)
    o = segment_overlaps(space)
    return TheoryReport(non_conflicting=not c, disjoint_segments=not o, conflicts=c, overlaps=o)
