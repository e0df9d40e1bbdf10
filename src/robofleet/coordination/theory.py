"""Checks of the theory's preconditions (paper 000, Definition 4 and Theorem 4).

* Definition 4 — *non-conflicting* trajectories: no robot's path comes within ``2r`` of
  another robot's start or goal. Then (Theorems 1, 2) a deadlock happens exactly when
  the active segment graph has a cycle.
* Theorem 4 — *disjoint collision segments*: for every robot the step ranges of its
  collision segments (Definition 2, ``{s, …, f − 1}`` with ``s = L`` the step reaching
  the obstacle and ``f = R + 1`` the step clearing it) are pairwise disjoint. Then no flip
  can close a cycle. In discrete time we need one step between them (``f(c) < s(c')``):
  with ``f(c) = s(c')`` clearing one obstacle *is* entering the next, and a cycle can close
  through that single moment. The result also relies on flips happening only at the
  obstacle's entrance (see :mod:`.label_flipping`): for labels chosen arbitrarily, three
  robots circling a triangle of crossings deadlock although their segments are disjoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

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
    c = conflicts(traj)
    o = segment_overlaps(space)
    return TheoryReport(non_conflicting=not c, disjoint_segments=not o, conflicts=c, overlaps=o)
