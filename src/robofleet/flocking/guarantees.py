"""The checkable conditions of Gervasi & Prencipe (TR-01-24, 2001) for one scenario.

:func:`check` reports, before anything runs (what ``robofleet check`` prints):

* the robot model of Sec. 2: assumptions A1 (cycles finite and bounded below), A2
  (every Move covers at least δ_f, or reaches a destination closer than that), A3 (Look
  and Compute take no time), and Observation 3.1 (a common unit of length);
* the pattern conditions of Sec. 4.1: lb-symmetry (item 2), at most one point on the
  L-B axis (item 3), the pattern directed along B → L (item 1, for the directed
  problem), whether the ranking of lines 12-28 can hold a follower on the on-axis slot
  (not stated by the paper: the slot must be nearer to L than every off-axis slot,
  :meth:`.patterns.Pattern.axis_slot_ranked_ahead`, unless ``algorithm.ranking:
  axis_slot_nearest``), and whether the chosen algorithm can form the pattern (Secs.
  4.1, 6.1-6.4);
* conditions (1)-(3) of Sec. 3.2 a priori: the leader's speed and turn rate against the
  slowest follower the spec allows, Σ_i k^{f_i} with the longest Move the scheduler
  allows against ξ; condition (4), which (3) implies. Each run also measures (1)-(4) on
  its cycle log (results ``condition_1`` … ``condition_4``).

A pattern drawn per seed (``kind: random``) is checked on the seed-0 draw; random
patterns are lb-symmetric with at most one axis point by construction (Sec. 4.2).
"""

from __future__ import annotations

import numpy as np

from ..core.family import Guarantee, expect_spec
from ..core.rng import keyed_generator
from .leader import ConditionReport, check_conditions, resolve_speeds
from .patterns import Pattern
from .spec import (
    ANY_PATTERN,
    AUTO_XI_FACTOR,
    HEADING_BASED,
    Spec,
    pattern_limitation,
    ranking_limitation,
)


def formable_consequence(kind: str) -> str:
    """What the paper says algorithm ``kind`` achieves on a pattern it can form."""
    if kind in ANY_PATTERN:
        return "it forms any pattern (Secs. 6.2.3, 6.2.4, 6.4; without common chirality up to reflection)"
    if kind in HEADING_BASED:
        return "it forms the directed target along the leader's heading (Secs. 6.1, 6.3)"
    return "it statistically solves approximate undirected flocking (Secs. 4.1, 5)"


def check(spec: Spec) -> list[Guarantee]:
    """The model assumptions, pattern conditions and leader conditions of the paper for ``spec``.

    Parameters
    ----------
    spec:
        A validated flocking scenario.

    Returns
    -------
    list of Guarantee
        A1, A2, A3, Observation 3.1; lb-symmetry, points on the axis, directed pattern,
        the on-axis slot's ranking, the algorithm's pattern requirement; conditions (1),
        (2), (3), (4) of Sec. 3.2.
    """
    expect_spec(spec, Spec, "flocking")  # input validation: a validated flocking scenario
    pattern = spec.pattern.build(rng=keyed_generator(0, "pattern"), source=spec.source)
    return model_guarantees(spec) + pattern_guarantees(spec, pattern) + leader_guarantees(spec, pattern)


def model_guarantees(spec: Spec) -> list[Guarantee]:
    """Assumptions A1-A3 of Sec. 2 on the scheduler, and Observation 3.1."""
    s = spec.scheduler
    cycle = f"τ ~ U({s.cycle_min:g}, {s.cycle_max:g})" if s.kind == "async" else "rounds of one time unit"
    v_min = spec.followers.slowest_speed
    shortest = s.rigidity * v_min * s.move_time_min
    return [
        Guarantee("cycles finite and bounded below", "A1", s.move_time_min > 0 and np.isfinite(s.move_time_max),
                  f"{s.kind}: {cycle}", f"{s.kind}: {cycle}"),
        Guarantee("every Move covers at least δ_f", "A2", s.min_move <= shortest,
                  f"δ_f = {s.min_move:g} exceeds rigidity · slowest v_f · shortest Move = {shortest:.4g}: the run is refused",
                  f"δ_f = {s.min_move:g} ≤ rigidity · slowest v_f · shortest Move = {shortest:.4g}; destinations closer than δ_f are reached"),
        Guarantee("Look and Compute take no time", "A3", True, consequence="the Move starts at the Look; a follower may be seen while moving"),
        Guarantee("common unit of length", "Observation 3.1", True,
                  consequence="local frames differ in origin, rotation and chirality only"),
    ]


def pattern_guarantees(spec: Spec, pattern: Pattern) -> list[Guarantee]:
    """Sec. 4.1 items 1-3 on the pattern, and the chosen algorithm's requirement (Secs. 4.1, 6)."""
    drawn = " (random pattern: lb-symmetric by construction; checked on the seed-0 draw)" if spec.pattern.kind == "random" else ""
    kind = spec.algorithm.kind
    limitation = pattern_limitation(kind, pattern)
    ranking = ranking_limitation(spec.algorithm, pattern)
    needs = f"it needs {limitation}" if limitation else (
        "its ranking cannot hold the on-axis slot (see above); algorithm.ranking: axis_slot_nearest forms it (beyond the paper)")
    on_axis = f"{pattern.n_on_axis} point{'' if pattern.n_on_axis == 1 else 's'} on the axis"
    return [
        Guarantee("lb-symmetric pattern", "Sec. 4.1, item 2", pattern.is_lb_symmetric,
                  f"ℙ ({pattern.name}) is not symmetric about the line through L and B_P: followers without common chirality "
                  "may disagree on the formation (Fig. 6); formed at best up to reflection",
                  f"the two semi-patterns are indistinguishable, so any chirality agrees{drawn}"),
        Guarantee("at most one pattern point on the L-B axis", "Sec. 4.1, item 3", pattern.n_on_axis <= 1,
                  f"{on_axis}: two followers may rank equal and pick the same slot (Fig. 7)", on_axis),
        Guarantee("pattern directed along B → L", "Sec. 4.1, item 1", pattern.is_directed,
                  "B_P is off the pattern's negative x axis: the estimated heading B → L differs from the leader's, "
                  "so Δ_e ≤ ξ does not give Δ_r ≤ ξ",
                  "the estimated target is the real one when the leader goes straight (directed flocking)"),
        axis_slot_guarantee(spec, pattern, ranking, drawn),
        Guarantee(f"algorithm {kind!r} can form the pattern", "Secs. 4.1, 6.1-6.4", not limitation and not ranking,
                  needs, formable_consequence(kind)),
    ]


def axis_slot_guarantee(spec: Spec, pattern: Pattern, limitation: str, drawn: str = "") -> Guarantee:
    """Whether the ranking of Algorithm 1 (lines 12-28) can hold a follower on the
    pattern's on-axis slot (:func:`.spec.ranking_limitation`); ``drawn`` notes a pattern
    drawn per seed (checked on one draw)."""
    drawn = " (random pattern: checked on the seed-0 draw, other draws may differ)" if drawn else ""
    if pattern.n_on_axis != 1:
        holds_because = f"{pattern.n_on_axis} on-axis slots: nothing to rank against"
    elif spec.algorithm.ranking != "paper":
        holds_because = ("ranking axis_slot_nearest (beyond the paper): the followers sent to the on-axis slot are the "
                         "ones nearest to it")
    elif spec.algorithm.kind == "stripe":
        holds_because = "the stripe ranking (distance from Y first) puts the on-axis slot behind every other"
    else:
        holds_because = "it is nearer to the leader than every off-axis slot, so the follower heading for it ranks last"
    return Guarantee("ranking can hold the on-axis slot", "Algorithm 1, lines 12-28", not limitation,
                     f"{limitation} (set algorithm.ranking: axis_slot_nearest, beyond the paper){drawn}",
                     holds_because + drawn)


def leader_guarantees(spec: Spec, pattern: Pattern) -> list[Guarantee]:
    """Conditions (1)-(4) of Sec. 3.2 a priori, against the slowest follower the spec allows."""
    report = a_priori_conditions(spec, pattern)
    holds = report.holds
    v, w, r, vmin = report.v_leader, report.omega_leader, report.radius, report.v_min
    slot = f"v_L + ω_L R_P = {v:.4g} + {w:.4g} · {r:.4g} = {report.slot_speed:.4g}"
    tau = spec.scheduler.move_time_max
    sum_k = f"Σ k^f = {pattern.size} · {report.slot_speed:.4g} · {tau:g} = {report.sum_k:.4g}"
    return [
        Guarantee("leader slower than every follower", "Sec. 3.2, (1)", holds["condition_1"],
                  f"v_L = {v:.4g} ≥ slowest v_f = {vmin:.4g}", f"v_L = {v:.4g} < slowest v_f = {vmin:.4g}"),
        Guarantee("slots slower than every follower", "Sec. 3.2, (2)", holds["condition_2"],
                  f"{slot} ≥ slowest v_f = {vmin:.4g}", f"{slot} < slowest v_f = {vmin:.4g}"),
        Guarantee("Moves short enough for ξ", "Sec. 3.2, (3)", holds["condition_3"],
                  f"{sum_k} > ξ = {report.xi:.4g}", f"{sum_k} ≤ ξ = {report.xi:.4g}"),
        Guarantee("Move durations short enough for ξ at every time, a priori", "Sec. 3.2, (4)", holds["condition_3"],
                  "not implied by (3); each run measures it on its cycle log (results: condition_4)",
                  "implied by (3), since τ̄_f(t) ≤ max_j τ_f^M(j)"),
    ]


def a_priori_conditions(spec: Spec, pattern: Pattern) -> ConditionReport:
    """Conditions (1)-(3) with the slowest follower the spec allows and the longest Move
    its scheduler allows; ξ as the run would set it (``auto``: 2 Σ_i k^{f_i})."""
    v_min = spec.followers.slowest_speed
    v, w = resolve_speeds(spec.leader, np.array([v_min]), pattern.radius)
    tau = spec.scheduler.move_time_max
    xi = AUTO_XI_FACTOR * pattern.size * (v + w * pattern.radius) * tau if spec.xi == "auto" else float(spec.xi)
    return check_conditions(v, w, pattern.radius, np.full(pattern.size, v_min), tau, xi, on_violation="ignore")
