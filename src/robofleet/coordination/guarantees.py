"""Checks of the theory's preconditions (the label-flipping deadlock paper (2021), Definition 4 and Theorem 4), and
:func:`check`, what ``robofleet check`` prints for a scenario (the plan checks themselves
live in :mod:`.theory`, which the instance cache also uses).

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

from ..core.family import Guarantee, expect_spec
from .coordination_space import CoordinationSpace
from .instance import prepare_instance
from .plan_execution import Method
from .segment_graph import Resolution
from .spec import Spec
from .theory import Conflict, Overlap, TheoryReport, check_theory, conflicts, segment_overlaps
from .trajectories import Trajectories

__all__ = ["Conflict", "Overlap", "TheoryReport", "check", "check_theory", "conflicts", "segment_overlaps"]


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
    drawn = spec.robots.placement != "explicit" and spec.robots.instance_seed is None and spec.trajectories is None
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
    * ``method: btpg`` — every labeling first come can produce is acyclic (the offline
      classification, :mod:`.btpg`); no deadlock iff Definition 4 holds (Theorems 1, 2).
    * ``method: optimal`` — every labeling kept leaves the segment graph acyclic
      (:mod:`.optimal`); no deadlock iff Definition 4 holds (Theorems 1, 2).
    """
    policy = spec.policy
    name = "no deadlock under this policy"
    if policy.method is Method.RMTRACK:
        return Guarantee(name, "RMTRACK, Čáp, Gregoire & Frazzoli 2016", True,
                         consequence=f"method rmtrack keeps the plan's order: the robot furthest behind is never blocked{where}")
    if policy.method in (Method.BTPG, Method.OPTIMAL):
        how = ("only obstacles whose switch closes no cycle under any labeling switch (offline classification)"
               if policy.method is Method.BTPG else "every labeling chosen keeps the segment graph acyclic")
        return Guarantee(name, "Theorems 1, 2", report.non_conflicting,
                         detail=(f"method {policy.method.value}: {how}, but Definition 4 fails: a deadlock need not close a "
                                 f"cycle{where}"),
                         consequence=f"method {policy.method.value}: {how}; only a cycle deadlocks{where}")
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
