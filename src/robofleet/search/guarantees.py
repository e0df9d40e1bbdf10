"""The paper's checkable conditions for one search scenario (Yang 2017), and what follows
from them: :func:`check`, what ``robofleet check`` prints.

The conditions on ranges and on the area (``r_safe > r_rob``, Assumptions 2.4, 2.5,
3.1.1–3.1.3, a connected grid) are computed by :func:`.assumptions.check_assumptions`; this module adds the
ones the scenario model enforces or decides — Assumption 2.1 (obstacles inside the area,
non-overlapping), Assumption 2.2 (robots start at different border vertices), the Table 1
design rule (ranges at the equalities of 2.4, 2.5 and 3.1.1), the triangular grid (Section
3), the choice rule (only the sequential choices with broadcast, rules (1)/(2), are
collision-free; RU and LFP are not) and working robots (Theorem 4.1 assumes no failures) —
and the three consequences: collision-free moves (Section 2), every accessible vertex
visited (Theorem 4.1) and a complete search of ``A_d`` (Theorem 4.1 with Section 3).
"""

from __future__ import annotations

import numpy as np

from ..core.family import Guarantee, expect_spec
from .assumptions import AssumptionCheck, AssumptionReport
from .decentralized import SequentialPolicy
from .grids import EPS, GridKind
from .spec import Algorithm, Spec

TABLE1_RANGES = {"r_rob": 0.26, "r_safe": 0.31}
"""Table 1 (simulation row): the robot radius and safety radius taken from the Pioneer 3-DX;
``r_so``, ``r_st``, ``r_c`` follow from the equalities of Assumptions 2.4, 3.1.1 and 2.5."""

ASSUMPTION_NAMES = {
    "safety": ("r_safe > r_rob", "Section 2", "the safety radius covers the robot's body and its errors"),
    "2.4": ("r_so >= a + r_safe", "Assumption 2.4", "every obstacle blocking an edge is sensed before the move"),
    "2.5": ("r_c >= 2a + r_safe - r_rob", "Assumption 2.5", "robots one or two vertices apart hear each other's choices"),
    "3.1.1": ("r_st >= a + r_safe", "Assumption 3.1.1", "areas near inaccessible vertices are detected from their neighbours"),
    "3.1.2": ("concave boundary curvature <= 1/r_st", "Assumption 3.1.2", "no pocket of A_d is out of target-sensing range"),
    "3.1.3": ("passages >= a + 2 r_safe wide", "Assumption 3.1.3", "at least one accessible route through every passage"),
    "connected": ("accessible vertices connected", "Assumptions 2.1, 3.1.3 on the grid",
                  "every accessible vertex can be reached from every start (no pocket sealed off)"),
}
"""Per assumption: the name shown, the paper's reference, and what follows when it holds."""


def check(spec: Spec) -> list[Guarantee]:
    """The paper's checkable conditions for one search scenario, and what follows from them.

    Parameters
    ----------
    spec:
        A validated search scenario.

    Returns
    -------
    list of Guarantee
        Assumption 2.1, 2.2, ``r_safe > r_rob``, 2.4, 2.5, 3.1.1–3.1.3 and the connected
        grid (from :func:`.assumptions.check_assumptions`), the Table 1 design rule, the triangular grid (Section
        3), the choice rule, working robots, and the three consequences: collision-free
        moves, every accessible vertex visited (Theorem 4.1) and a complete search of
        ``A_d`` (Theorem 4.1 with Section 3).
    """
    expect_spec(spec, Spec, "search")  # input validation: a validated search scenario
    report = spec.assumption_report()
    conditions = [area_condition(spec), starts_condition(spec)]
    conditions += [assumption_guarantee(c) for c in report.checks]
    conditions += [table1_condition(spec), grid_condition(spec), choice_condition(spec), failure_condition(spec)]
    return conditions + consequences(spec, report)


def area_condition(spec: Spec) -> Guarantee:
    """Assumption 2.1: a bounded area with non-overlapping obstacles inside it (the scenario
    model refuses anything else, so this always holds for a validated spec)."""
    n = len(spec.workspace.obstacles)
    return Guarantee("bounded area, obstacles inside it and non-overlapping", "Assumption 2.1", True,
                     detail=f"{n} obstacle(s)", consequence=f"A_d = A minus {n} obstacle(s) is the area to detect")


def starts_condition(spec: Spec) -> Guarantee:
    """Assumption 2.2: the robots start at different vertices along the border of the area.

    Drawn starts (``robots.count``) are distinct border vertices by construction; given
    ``starts`` are distinct accessible vertices (validated) and checked here to lie on the
    border ring (:meth:`.grids.Grid.border_vertices`).
    """
    if spec.robots.starts is None:
        return Guarantee("robots start at different border vertices", "Assumption 2.2", True,
                         consequence=f"{spec.robots.count} distinct border vertices drawn per seed")
    grid = spec.built_grid()
    ids = grid.nearest_vertex(np.asarray(spec.robots.starts, dtype=float))[0]
    border = set(grid.border_vertices().tolist())
    inner = [k for k, v in enumerate(ids) if v not in border]
    return Guarantee("robots start at different border vertices", "Assumption 2.2", not inner,
                     detail=f"starts {inner} are not border vertices" if inner else "",
                     consequence=f"{len(ids)} distinct border vertices")


def assumption_guarantee(c: AssumptionCheck) -> Guarantee:
    """One row of :func:`check_assumptions` as a :class:`Guarantee` (value against requirement)."""
    name, reference, consequence = ASSUMPTION_NAMES[c.name]
    evidence = c.evidence or f"{c.value:.4g} against {c.required:.4g}"
    return Guarantee(name, reference, c.holds, detail=f"{evidence} ({c.statement})", consequence=f"{consequence} ({evidence})")


def table1_condition(spec: Spec) -> Guarantee:
    """Table 1 (simulation row): ``r_rob``, ``r_safe`` of the Pioneer 3-DX and the other
    ranges at the equalities of Assumptions 2.4 (``r_so = a + r_safe``), 3.1.1
    (``r_st = a + r_safe``) and 2.5 (``r_c = 2a + r_safe − r_rob``) for the scenario's ``a``."""
    r, a = spec.ranges, spec.grid.a
    wanted = {**TABLE1_RANGES, "r_so": a + TABLE1_RANGES["r_safe"], "r_st": a + TABLE1_RANGES["r_safe"],
              "r_c": 2 * a + TABLE1_RANGES["r_safe"] - TABLE1_RANGES["r_rob"]}
    differ = [f"{k} = {getattr(r, k):g} (Table 1: {v:g})" for k, v in wanted.items() if abs(getattr(r, k) - v) > EPS]
    return Guarantee("ranges of Table 1 (equalities of 2.4, 2.5, 3.1.1)", "Table 1", not differ,
                     detail=", ".join(differ), consequence=f"the paper's simulation setting at a = {a:g}")


def grid_condition(spec: Spec) -> Guarantee:
    """Section 3: only the triangular grid has the complete-search guarantee."""
    kind = spec.grid.kind
    return Guarantee("triangular grid", "Section 3", kind is GridKind.TRIANGULAR, detail=f"{kind.value} grid",
                     consequence="the grid for which Assumptions 3.1.1-3.1.2 give a complete search")


def choice_condition(spec: Spec) -> Guarantee:
    """Section 4.2 (steps 4–5): sequential choices broadcast to the neighbours one and two
    vertices away (rules (1)/(2), :class:`.decentralized.SequentialPolicy`). RU and LFP
    choose simultaneously and may collide."""
    sequential = spec.algorithm in (Algorithm.PROPOSED, Algorithm.RULE1) and SequentialPolicy.collision_free
    return Guarantee("sequential choices with broadcast (rules (1)/(2))", "Section 4.2, steps 4-5", sequential,
                     detail=f"algorithm {spec.algorithm.value} chooses simultaneously, collisions allowed",
                     consequence=f"algorithm {spec.algorithm.value}: no two robots pick one vertex or swap along an edge")


def failure_condition(spec: Spec) -> Guarantee:
    """Theorem 4.1 assumes working robots; injected failures (``failures``,
    ``random_failures``) block vertices the theorem counts on."""
    failing = len(spec.failures) + spec.random_failures.count
    return Guarantee("no robot failures", "Theorem 4.1", failing == 0,
                     detail=f"{failing} robot failure(s) injected: their vertices become blocked",
                     consequence="every robot keeps moving and answering")


def consequences(spec: Spec, report: AssumptionReport) -> list[Guarantee]:
    """What follows (Section 2, Theorem 4.1, Section 3) when the conditions above hold."""
    sequential = choice_condition(spec).holds
    working = failure_condition(spec).holds
    holds = {c.name: c.holds for c in report.checks}
    target = "all targets are found" if spec.situation == 1 else "every point of A_d is within r_st of a visited vertex"
    return [
        Guarantee("collision-free search", "Section 2, Assumptions 2.4-2.5", report.collision_free and sequential,
                  detail=why_not(("safety, 2.4, 2.5", report.collision_free), ("sequential choices", sequential)),
                  consequence="no robot collides with another robot, an obstacle or the border"),
        Guarantee("every accessible vertex visited", "Theorem 4.1", report.vertex_complete and sequential and working,
                  detail=why_not(("collision-free", report.collision_free), ("3.1.3", holds["3.1.3"]),
                                 ("connected grid", holds["connected"]), ("sequential choices", sequential),
                                 ("no failures", working)),
                  consequence=f"with probability 1, stop rule ({3 if spec.situation == 1 else 4}) fires after a finite time"),
        Guarantee("complete search of A_d", "Theorem 4.1, Section 3", report.complete_search and sequential and working,
                  detail=why_not(("sequential choices", sequential), ("no failures", working)) or report.guarantee,
                  consequence=f"with probability 1 {target} (stop rule ({3 if spec.situation == 1 else 4}))"),
    ]


def why_not(*conditions: tuple[str, bool]) -> str:
    """``"fails: a, b"`` naming the conditions that do not hold (``""`` if all do)."""
    failed = [name for name, holds in conditions if not holds]
    return "fails: " + ", ".join(failed) if failed else ""
