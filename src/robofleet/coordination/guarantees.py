"""Checks of the theory's preconditions (the label-flipping deadlock paper (2021), Definition 4 and Theorem 4), and
:func:`check`, what ``robofleet check`` prints for a scenario.

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

from ..core import arguments
from ..core.family import Guarantee, expect_spec
from .coordination_space import CoordinationSpace
from .instance import prepare_instance
from .plan_execution import Method
from .segment_graph import Resolution
from .spec import Spec
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


def check(spec: Spec, seed: int = 0) -> list[Guarantee]:
    """Plan (or read) a scenario's trajectories and evaluate the paper's conditions on them.

    Parameters
    ----------
    spec:
        The scenario.
    seed:
        The run seed whose instance is checked when ``robots.instance_seed`` is null (every
        run seed then draws its own instance); ignored otherwise.

    Returns
    -------
    list[Guarantee]
        The conditions — the plan is collision-free (RMTRACK's premise, Čáp, Gregoire &
        Frazzoli 2016), non-conflicting (Definition 4), has disjoint collision segments
        (Theorem 4) — each with its evidence, then what follows for the scenario's policy:
        a collision-free execution, and whether any result rules out a deadlock
        (:func:`deadlock_guarantee`).
    """
    expect_spec(spec, Spec, "coordination")  # input validation: a validated coordination scenario
    instance = prepare_instance(spec, seed)
    report = check_theory(instance.trajectories, instance.space)
    where = instance_note(spec, seed)
    return [plan_guarantee(instance.trajectories, instance.space, where), non_conflicting_guarantee(report, where),
            disjoint_guarantee(report, where), safety_guarantee(spec, where), deadlock_guarantee(spec, report, where)]


def instance_note(spec: Spec, seed: int) -> str:
    """`` (instance of run seed s)`` when the checked instance depends on the run seed, else ``""``."""
    drawn = spec.robots.placement == "flows" and spec.robots.instance_seed is None and spec.trajectories is None
    return f" (instance of run seed {seed}; robots.instance_seed is null)" if drawn else ""


def plan_guarantee(traj: Trajectories, space: CoordinationSpace, where: str = "") -> Guarantee:
    """The plan is collision-free (else building its coordination space fails): RMTRACK's premise."""
    detail = (f"{traj.n_robots} robots, {space.n_obstacles} coordination-space obstacles, "
              f"longest trajectory {int(traj.lengths.max())} steps{where}")
    return Guarantee("collision-free plan", "RMTRACK, Čáp, Gregoire & Frazzoli 2016", True, detail,
                     f"RMTRACK without flips is safe and deadlock-free; {detail}")


def non_conflicting_guarantee(report: TheoryReport, where: str = "") -> Guarantee:
    """Definition 4, with its first violation as evidence."""
    detail = ""
    if report.conflicts:
        c = report.conflicts[0]
        detail = (f"{len(report.conflicts)} conflicts; first: robot {c.robot} at step {c.step} is within 2r of "
                  f"the {c.which} of robot {c.other}; Theorems 1, 2 do not apply: a deadlock need not close a cycle{where}")
    consequence = f"deadlock ⇔ cycle in the active segment graph (Theorems 1, 2): the deadlock check prevents every deadlock{where}"
    return Guarantee("non-conflicting", "Definition 4", report.non_conflicting, detail, consequence)


def disjoint_guarantee(report: TheoryReport, where: str = "") -> Guarantee:
    """Theorem 4's condition, with its first violation as evidence. Theorem 4 gives an
    acyclic segment graph; that this means no deadlock takes Definition 4 as well."""
    detail = ""
    if report.overlaps:
        o = report.overlaps[0]
        detail = (f"{len(report.overlaps)} overlaps, a flip can close a cycle; first: robot {o.robot}: steps "
                  f"{o.first[0]}..{o.first[1]} (with robot {o.others[0]}) and {o.second[0]}..{o.second[1]} "
                  f"(with robot {o.others[1]}){where}")
    no_cycle = "no flip at an obstacle's entrance can close a cycle"
    consequence = (f"{no_cycle}: no deadlock{where}" if report.non_conflicting else
                   f"{no_cycle}, but Definition 4 fails, so an acyclic graph does not rule out a deadlock{where}")
    return Guarantee("disjoint collision segments", "Theorem 4", report.disjoint_segments, detail, consequence)


def safety_guarantee(spec: Spec, where: str = "") -> Guarantee:
    """Safety of the execution: Eq. 1 keeps every robot out of the coordination-space
    obstacles under the current labels, and a flip is only tried while the other robot
    has not reached the obstacle (:func:`.label_flipping.flip_eligible`), when the new
    label's invariant holds trivially. Holds for every collision-free plan and policy."""
    flips = "" if spec.policy.method is Method.RMTRACK else "; flips only before the other robot reaches the obstacle"
    return Guarantee("collision-free execution", "Eq. 1", True,
                     consequence=f"no two robots come closer than 2r, whatever the disturbances{flips}{where}")


def deadlock_guarantee(spec: Spec, report: TheoryReport, where: str = "") -> Guarantee:
    """Whether a result rules out a deadlock for the scenario's policy, and which one.

    * ``method: rmtrack`` — the plan's labels never change: deadlock-free (RMTRACK).
    * flips with ``deadlock_check`` — a flip that closes a cycle is refused; no deadlock
      iff Definition 4 holds (Theorems 1, 2: then a deadlock is a cycle). The literal
      Definition 3 graph (``resolution: definition3``) holds every exact cycle, so its
      check is conservative.
    * flips without the check — no deadlock when Definition 4 and Theorem 4's condition
      both hold (no flip closes a cycle, and only cycles deadlock).
    """
    policy = spec.policy
    name = "no deadlock under this policy"
    if policy.method is Method.RMTRACK:
        return Guarantee(name, "RMTRACK, Čáp, Gregoire & Frazzoli 2016", True,
                         consequence=f"method rmtrack keeps the plan's order: the robot furthest behind is never blocked{where}")
    flips = f"method {policy.method.value}"
    if policy.deadlock_check:
        graph = ("the literal Definition 3 graph, conservative: it may refuse harmless flips"
                 if policy.resolution is Resolution.DEFINITION3 else "the exact segment graph")
        return Guarantee(name, "Theorems 1, 2", report.non_conflicting,
                         detail=(f"{flips} with the deadlock check, but Definition 4 fails: a deadlock need not close a "
                                 f"cycle, so refusing cycles does not rule it out{where}"),
                         consequence=f"{flips}: every flip that would close a cycle is refused ({graph}){where}")
    failed = [why for why, holds in (("Definition 4 fails", report.non_conflicting),
                                     ("collision segments overlap, so a flip can close a cycle", report.disjoint_segments))
              if not holds]
    return Guarantee(name, "Theorems 2, 4", not failed,
                     detail=f"{flips} without the deadlock check: {'; '.join(failed)}{where}",
                     consequence=f"{flips} without the deadlock check: no flip can close a cycle, and only a cycle deadlocks{where}")
