"""The paper's checkable conditions: its assumptions, and what the completeness guarantee
then means (:func:`check`, what ``robofleet check`` prints for a search scenario).

Paper 002:

* 2.4  ``r_so ≥ a + r_safe`` — a robot senses every obstacle blocking an edge it may take.
* 2.5  ``r_c ≥ 2a + r_safe − r_rob`` — robots one or two vertices apart communicate, so
  sequential choices with broadcast avoid every collision.
* Section 2: ``r_safe > r_rob`` (the safety radius includes all errors).
* 3.1.1 ``r_st ≥ a + r_safe`` — areas near inaccessible vertices are detected from their
  accessible neighbours (Fig. 2, area D).
* 3.1.2 the curvature of the concave parts of the area is at most ``1/r_st``. A polygon's
  corners have unbounded curvature, so we read the assumption at the scale ``r_st``: along
  the boundary of ``A_d`` (interior on the left), the boundary may turn towards the area by
  at most 1 rad within any stretch of length ``r_st`` — what an arc of radius ``r_st`` does.
  A rounded corner of radius ``≥ r_st`` passes, a right-angled corner of the border (a
  turn of π/2 at one point) or a notch in an obstacle fails; convex obstacles never fail
  (their corners turn away from the area). Sections A–C of Fig. 2 fail it.
* 3.1.3 passages between obstacles, or between obstacles and the border, are at least
  ``W_pass = a + 2 r_safe`` wide (Fig. 3).

Theorem 4.1 (all assumptions, rules (1)/(2) with (3) or (4)): with probability 1 all
targets are found (situation 1) or all vertices detected (situation 2); Section 3: only the
triangular grid turns the latter into a complete search of ``A_d``.

:func:`check` reports these for one scenario as :class:`~robofleet.core.family.Guarantee`
s, together with the conditions the scenario model already enforces or decides: Assumption
2.1 (obstacles inside the area, non-overlapping), Assumption 2.2 (robots start at
different border vertices), the Table 1 design rule (ranges at the equalities of 2.4, 2.5
and 3.1.1), the choice rule (only the sequential choices with broadcast, rules (1)/(2),
are collision-free; RU and LFP are not) and working robots (Theorem 4.1 assumes no
failures).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import Polygon

from ..core.family import Guarantee
from ..core.workspace import Workspace
from .decentralized import SequentialPolicy
from .grids import EPS, GridKind
from .simulation import Algorithm

if TYPE_CHECKING:
    from .spec import Spec


@dataclass(frozen=True)
class AssumptionCheck:
    """One assumption: ``holds`` when ``value`` satisfies ``required`` (both in area units)."""

    name: str
    statement: str
    holds: bool
    value: float
    required: float

    def __post_init__(self):
        object.__setattr__(self, "holds", bool(self.holds))
        object.__setattr__(self, "value", float(self.value))
        object.__setattr__(self, "required", float(self.required))


@dataclass(frozen=True)
class AssumptionReport:
    """All checks, and what Theorem 4.1 guarantees under them."""

    checks: tuple[AssumptionCheck, ...]
    grid_kind: GridKind
    collision_free: bool
    vertex_complete: bool
    complete_search: bool
    guarantee: str

    def failed(self) -> list[AssumptionCheck]:
        return [c for c in self.checks if not c.holds]

    def as_dict(self) -> dict:
        """Plain mapping for JSON output / trace metadata."""
        return {
            "checks": {c.name: {"holds": c.holds, "value": c.value, "required": c.required, "statement": c.statement} for c in self.checks},
            "grid": self.grid_kind.value,
            "collision_free": self.collision_free,
            "vertex_complete": self.vertex_complete,
            "complete_search": self.complete_search,
            "guarantee": self.guarantee,
        }


def max_boundary_turn(workspace: Workspace, window: float) -> float:
    """Largest turn (rad) towards ``A_d`` of its boundary within a stretch of length ``window``.

    Rings are traversed with ``A_d`` on the left (outer border counter-clockwise, obstacles
    clockwise); a left turn bends the boundary around the area (a pocket), a right turn away
    from it. Returns the maximum over all stretches of the sum of signed turns. O(V²) per ring.
    """
    rings = [np.asarray(workspace.bounds, dtype=float)]
    rings += [np.asarray(o, dtype=float)[::-1] for o in workspace.obstacles]  # stored ccw -> cw
    worst = 0.0
    for ring in rings:
        if np.allclose(ring[0], ring[-1]):
            ring = ring[:-1]
        edge = np.roll(ring, -1, axis=0) - ring
        heading = np.arctan2(edge[:, 1], edge[:, 0])
        turn = (heading - np.roll(heading, 1) + np.pi) % (2 * np.pi) - np.pi  # turn at each vertex
        length = np.linalg.norm(edge, axis=1)
        start = np.concatenate([[0.0], np.cumsum(length)])  # arc length at each vertex
        total = start[-1]
        pos = np.concatenate([start[:-1], start[:-1] + total])
        turns = np.concatenate([turn, turn])
        for i in range(len(ring)):
            inside = (pos >= pos[i] - EPS) & (pos <= pos[i] + window + EPS)
            worst = max(worst, float(turns[inside].sum()))
    return worst


def narrowest_passage(workspace: Workspace) -> float:
    """Smallest positive gap between two obstacles or between an obstacle and the border."""
    parts = [Polygon(o) for o in workspace.obstacles]
    border = workspace.boundary_polygon.exterior
    gaps = [shapely.distance(p, border) for p in parts]
    gaps += [shapely.distance(p, q) for i, p in enumerate(parts) for q in parts[i + 1:]]
    positive = [g for g in gaps if g > EPS]
    return float(min(positive)) if positive else float("inf")


def check_assumptions(workspace: Workspace, kind: GridKind | str, a: float, r_rob: float, r_safe: float,
                      r_so: float, r_st: float, r_c: float) -> AssumptionReport:
    """Evaluate Assumptions 2.4, 2.5, 3.1.1–3.1.3 (and ``r_safe > r_rob``) for an instance."""
    kind = GridKind(kind)
    turn = max_boundary_turn(workspace, r_st)
    passage = narrowest_passage(workspace)
    checks = (
        AssumptionCheck("safety", "r_safe > r_rob", bool(r_safe > r_rob), float(r_safe), float(r_rob)),
        AssumptionCheck("2.4", "r_so >= a + r_safe", r_so >= a + r_safe - EPS, r_so, a + r_safe),
        AssumptionCheck("2.5", "r_c >= 2a + r_safe - r_rob", r_c >= 2 * a + r_safe - r_rob - EPS, r_c, 2 * a + r_safe - r_rob),
        AssumptionCheck("3.1.1", "r_st >= a + r_safe", r_st >= a + r_safe - EPS, r_st, a + r_safe),
        AssumptionCheck("3.1.2", "boundary turn towards A_d within any length r_st <= 1 rad (curvature <= 1/r_st)",
                        turn <= 1.0 + 1e-6, turn, 1.0),
        AssumptionCheck("3.1.3", "passage width >= a + 2 r_safe", passage >= a + 2 * r_safe - EPS, passage, a + 2 * r_safe),
    )
    ok = {c.name: c.holds for c in checks}
    collision_free = ok["safety"] and ok["2.4"] and ok["2.5"]
    vertex_complete = collision_free and ok["3.1.3"]
    complete = vertex_complete and ok["3.1.1"] and ok["3.1.2"] and kind is GridKind.TRIANGULAR
    return AssumptionReport(checks, kind, collision_free, vertex_complete, complete, guarantee_text(collision_free, vertex_complete, complete, kind))


def guarantee_text(collision_free: bool, vertex_complete: bool, complete: bool, kind: GridKind) -> str:
    """What Theorem 4.1 and Section 3 promise for this instance, in one sentence."""
    if complete:
        return ("Theorem 4.1 applies: no collisions; with probability 1 all targets are found (situation 1) and every "
                "accessible vertex is visited, so every point of A_d is within r_st of a visited vertex (situation 2).")
    if not collision_free:
        return ("No guarantee: with r_so < a + r_safe a blocked edge may go unsensed, with r_c < 2a + r_safe - r_rob "
                "robots one or two vertices apart may not hear each other's choices, so collisions are possible.")
    if not vertex_complete:
        return ("Collision-free, but a passage narrower than a + 2 r_safe may cut the accessible vertices apart: only the "
                "vertices connected to the starts are guaranteed to be visited.")
    why = "the grid is not triangular (Section 3)" if kind is not GridKind.TRIANGULAR else "r_st or the area's pockets violate 3.1.1/3.1.2"
    return ("Collision-free and every accessible vertex is visited with probability 1, but the search of A_d may be "
            f"incomplete because {why}: points farther than r_st from every accessible vertex stay undetected.")


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
        Assumption 2.1, 2.2, ``r_safe > r_rob``, 2.4, 2.5, 3.1.1–3.1.3 (from
        :func:`check_assumptions`), the Table 1 design rule, the triangular grid (Section
        3), the choice rule, working robots, and the three consequences: collision-free
        moves, every accessible vertex visited (Theorem 4.1) and a complete search of
        ``A_d`` (Theorem 4.1 with Section 3).
    """
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
    evidence = f"{c.value:.4g} against {c.required:.4g}"
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
    target = "all targets are found" if spec.situation == 1 else "every point of A_d is within r_st of a visited vertex"
    return [
        Guarantee("collision-free search", "Section 2, Assumptions 2.4-2.5", report.collision_free and sequential,
                  detail=why_not(("safety, 2.4, 2.5", report.collision_free), ("sequential choices", sequential)),
                  consequence="no robot collides with another robot, an obstacle or the border"),
        Guarantee("every accessible vertex visited", "Theorem 4.1", report.vertex_complete and sequential and working,
                  detail=why_not(("collision-free, 3.1.3", report.vertex_complete), ("sequential choices", sequential),
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
