"""Check of the paper's assumptions and what the completeness guarantee then means.

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
* connected grid: the accessible vertices form one component along travellable edges.
  Assumption 2.1 (a connected area) with 3.1.3 is meant to give it, but an obstacle that
  touches the border seals a pocket without any narrow passage (3.1.3 measures only gaps
  of positive width), and a coarse grid may miss a passage 3.1.3 accepts; the check reads
  the built grid itself. Theorem 4.1's proof needs it: a robot that starts in a pocket can
  only visit the pocket.

Theorem 4.1 (all assumptions, rules (1)/(2) with (3) or (4)): with probability 1 all
targets are found (situation 1) or all vertices detected (situation 2); Section 3: only the
triangular grid turns the latter into a complete search of ``A_d``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import Polygon

from ..core.errors import ConfigError, short_repr
from ..core.workspace import Workspace
from .grids import EPS, Grid, GridKind, build_grid, check_grid_arguments


@dataclass(frozen=True)
class AssumptionCheck:
    """One assumption: ``holds`` when ``value`` satisfies ``required`` (both in area units)."""

    name: str
    statement: str
    holds: bool
    value: float
    required: float
    evidence: str = ""

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
            "checks": {c.name: {"holds": c.holds, "value": c.value, "required": c.required, "statement": c.statement,
                                **({"evidence": c.evidence} if c.evidence else {})} for c in self.checks},
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


def accessible_parts(grid: Grid) -> np.ndarray:
    """Sizes of the components of accessible vertices along travellable edges, largest first."""
    labels = grid.components[grid.accessible]
    return np.sort(np.unique(labels, return_counts=True)[1])[::-1]


def connectivity_check(grid: Grid) -> AssumptionCheck:
    """The grid-level premise of Theorem 4.1: one component of accessible vertices."""
    parts = accessible_parts(grid)
    sizes = " + ".join(str(int(k)) for k in parts[:6]) + (" + ..." if len(parts) > 6 else "")
    evidence = f"{len(parts)} part(s) of {sizes} accessible vertices" if len(parts) != 1 else f"1 part of {sizes} accessible vertices"
    return AssumptionCheck("connected", "one part of accessible vertices connected along travellable edges",
                           len(parts) <= 1, len(parts), 1, evidence)


def check_assumptions(workspace: Workspace, kind: GridKind | str, a: float, r_rob: float, r_safe: float,
                      r_so: float, r_st: float, r_c: float, grid: Grid | None = None) -> AssumptionReport:
    """Evaluate Assumptions 2.4, 2.5, 3.1.1–3.1.3 (and ``r_safe > r_rob``) for an instance,
    and whether its grid (``grid``, else built from the arguments) is connected."""
    kind = check_grid_arguments(workspace, kind, a, r_safe)  # input validation
    for name, value in (("r_rob", r_rob), ("r_so", r_so), ("r_st", r_st), ("r_c", r_c)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) or not 0 <= value < np.inf:
            raise ConfigError(f"{name}: expected a finite range ≥ 0, received {short_repr(value)}")
    grid = grid if grid is not None else build_grid(workspace, kind, a, r_safe)
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
        connectivity_check(grid),
    )
    ok = {c.name: c.holds for c in checks}
    collision_free = ok["safety"] and ok["2.4"] and ok["2.5"]
    vertex_complete = collision_free and ok["3.1.3"] and ok["connected"]
    complete = vertex_complete and ok["3.1.1"] and ok["3.1.2"] and kind is GridKind.TRIANGULAR
    text = guarantee_text(collision_free, vertex_complete, complete, kind, len(accessible_parts(grid)))
    return AssumptionReport(checks, kind, collision_free, vertex_complete, complete, text)


def guarantee_text(collision_free: bool, vertex_complete: bool, complete: bool, kind: GridKind, parts: int = 1) -> str:
    """What Theorem 4.1 and Section 3 promise for this instance, in one sentence."""
    if complete:
        return ("Theorem 4.1 applies: no collisions; with probability 1 all targets are found (situation 1) and every "
                "accessible vertex is visited, so every point of A_d is within r_st of a visited vertex (situation 2).")
    if not collision_free:
        return ("No guarantee: with r_so < a + r_safe a blocked edge may go unsensed, with r_c < 2a + r_safe - r_rob "
                "robots one or two vertices apart may not hear each other's choices, so collisions are possible.")
    if not vertex_complete and parts > 1:
        return (f"Collision-free, but the accessible vertices fall apart into {parts} parts (a pocket sealed by obstacles, "
                "or a passage the grid cannot cross): only the parts holding a robot are searched, a robot starting in a "
                "pocket searches only that pocket, and targets in a part without robots are never found.")
    if not vertex_complete:
        return ("Collision-free, but a passage narrower than a + 2 r_safe may cut the accessible vertices apart: only the "
                "vertices connected to the starts are guaranteed to be visited.")
    why = "the grid is not triangular (Section 3)" if kind is not GridKind.TRIANGULAR else "r_st or the area's pockets violate 3.1.1/3.1.2"
    return ("Collision-free and every accessible vertex is visited with probability 1, but the search of A_d may be "
            f"incomplete because {why}: points farther than r_st from every accessible vertex stay undetected.")
