"""The checkable conditions of Zhu et al. 2022 for one scenario (what ``robofleet check`` prints).

B-UAVC's guarantee (Sec. 4, with the ε-shadows of appendix A): a robot that stays in its
buffered uncertainty-aware Voronoi cell collides with each other robot, and with each
static obstacle, with probability at most δ at that step — given Gaussian estimates, a
chance buffer ``β = r_s + Φ⁻¹(√(1 − δ)) √(aᵀ Σ a)`` in every cell constraint and
ε-shadows with ``(1 − ε) √(1 − δ) ≥ 1 − δ``. :func:`check` evaluates, on the scenario
itself, what that needs:

1. the method builds chance-constrained cells (B-UAVC; BVC, inflated BVC and ORCA do not);
2. the obstacles and the workspace are convex (each is one half-space of a cell);
3. every robot starts inside its own initial B-UAVC (the premise: computed from the
   starts with the scenario's Σ, Σ_o and δ);
4. every team's controller keeps its robots inside their cells between steps;
5. then, the per-step bound: δ per robot pair and per robot–obstacle pair.
"""

from __future__ import annotations

import numpy as np

from ..core.family import Guarantee, expect_spec
from ..core.rng import as_generator
from ..core.spec_blocks import is_convex
from .cell import Cells, cell_rows
from .cell_model import cell_model, ground_section, method_setup
from .layout import initial_layout
from .spec import Spec, TeamSpec

LAYOUT_CHECK_SEED = 0
"""Seed of the random (antipodal) layout on which the start condition is evaluated."""
CONTAINMENT_TOL = 1e-9
KEEPS_CELL = {
    ("single_integrator", "one_step"): "one-step controller: the straight step toward g* stays in the convex cell",
    ("single_integrator", "mpc"): "MPC: every predicted position in the cell, straight segments between them",
    ("double_integrator", "one_step"): "braking rule (Sec. 5.2) on cells built from the braking segments: an accepted step keeps its Bézier hull and next braking segment in the cell",
}
"""Team kinds whose controller keeps each robot in its convex cell, and why."""
LEAVES_CELL = {
    ("double_integrator", "mpc"): "MPC constrains the sampled positions only; the parabola between them is not",
    ("unicycle", "one_step"): "three projections (Sec. 5.3): the RK2 arc of a step is not checked against the cell",
    ("unicycle", "mpc"): "MPC constrains the sampled positions only; the arcs between them are not",
    ("quadrotor", "mpc"): "MPC constrains the sampled positions only; the flight between them and the braking fallback are not",
}


def check(spec: Spec) -> list[Guarantee]:
    """The paper's conditions for ``spec``, evaluated (see the module docstring).

    Returns
    -------
    list of Guarantee
        Chance-constrained method, convex geometry, starts inside the cells,
        controllers keep the cells, and the resulting per-step collision bound.
    """
    expect_spec(spec, Spec, "avoidance")  # input validation: a validated avoidance scenario
    premises = [chance_constrained_method(spec), convex_geometry(spec), starts_inside_cells(spec), controllers_keep_cells(spec)]
    return premises + [per_step_bound(spec, premises)]


def chance_constrained_method(spec: Spec) -> Guarantee:
    """Whether the method's cells carry the chance constraint (B-UAVC, Sec. 4)."""
    noiseless = all(t.largest_sigma() == 0 for t in spec.team_specs()) and obstacle_sigma(spec) == 0
    why_not = {
        "bvc": "bvc builds its cells with Σ = Σ_o = 0 (deterministic BVC, Zhou et al. 2017): no chance constraint",
        "bvc_inflated": f"bvc_inflated grows r_s by {spec.inflation_sigmas:g} σ (a heuristic margin): no chance constraint",
        "orca": "orca (van den Berg et al. 2011) builds no cells and ignores Σ: no chance constraint",
    }.get(spec.method, "")
    if noiseless and spec.method in ("bvc", "bvc_inflated"):
        why_not += "; with zero noise, as here, BVC's deterministic collision avoidance applies instead"
    return Guarantee("chance-constrained cells (B-UAVC)", "Sec. 4: buffer β = r_s + Φ⁻¹(√(1 − δ))·√(aᵀΣa); appendix A: ε-shadows",
                     spec.method == "buavc", detail=why_not, consequence=f"cells built from Σ, Σ_o and δ = {spec.delta:g}")


def obstacle_sigma(spec: Spec) -> float:
    """The largest standard deviation of the obstacles' position (0 without obstacles)."""
    if spec.space3d is not None:
        return spec.space3d.obstacle_sigma if spec.space3d.boxes else 0.0
    if not spec.workspace.obstacles:
        return 0.0
    return float(np.sqrt(max(np.linalg.eigvalsh(spec.workspace.obstacle_covariance()).max(), 0.0)))


def convex_geometry(spec: Spec) -> Guarantee:
    """Whether every static obstacle and the workspace are convex (one half-space each per cell)."""
    reference = "Sec. 4: a cell is an intersection of half-spaces"
    if spec.space3d is not None:
        n = len(spec.space3d.boxes)
        return Guarantee("convex static obstacles and workspace", reference, True,
                         consequence=f"{n} box obstacle{'s' * (n != 1)} and the workspace box are convex")
    polygons = spec.workspace.obstacle_polygons()
    bad = [k for k, p in enumerate(polygons) if not is_convex(p)]
    bounds_ok = is_convex(spec.workspace.bounds_vertices())
    detail = ", ".join(([] if bounds_ok else ["the bounds"]) + [f"obstacle {k}" for k in bad])
    return Guarantee("convex static obstacles and workspace", reference, bounds_ok and not bad,
                     detail=f"not convex: {detail}" if detail else "",
                     consequence=f"{len(polygons)} convex obstacle{'s' * (len(polygons) != 1)} and convex bounds")


def starts_inside_cells(spec: Spec) -> Guarantee:
    """Whether every robot's start lies in its own initial B-UAVC, built from the starts
    (as the estimates' means) with the scenario's Σ, Σ_o and δ — the premise of the bound."""
    starts, _, slices = initial_layout(spec, as_generator(LAYOUT_CHECK_SEED))
    model = cell_model(spec, method_setup("buavc", spec.delta, spec.inflation_sigmas))
    n_obstacles = model.boxes.count if model.boxes is not None else model.geometry.obstacles.count
    cells = model.cells(starts, np.zeros((n_obstacles, spec.dim)))
    violations = np.concatenate([team_violation(team, team_cells(cells, team, sl, spec), starts[sl])
                                 for team, sl in zip(spec.team_specs(), slices)])
    random = any(t.layout.kind == "antipodal" for t in spec.team_specs())
    where = f"on the layout drawn with seed {LAYOUT_CHECK_SEED} (every seed's antipodal layout keeps these clearances)" if random else "at the starts"
    worst = int(np.argmax(violations))
    return Guarantee(
        "robots start inside their own B-UAVC", "Sec. 4: premise of the chance constraint", bool(violations.max(initial=0.0) <= CONTAINMENT_TOL),
        detail=f"{int((violations > CONTAINMENT_TOL).sum())} of {len(violations)} robots start outside their cell "
               f"(robot {worst} by {violations[worst]:.3g} m): closer to a robot, an obstacle or a wall than r_s + the chance buffer",
        consequence=f"all {len(violations)} robots {where}")


def team_cells(cells: Cells, team: TeamSpec, index: slice, spec: Spec) -> Cells:
    """A team's rows of the fleet's cells (the ground-plane section for ground robots in 3-D)."""
    rows = cell_rows(cells, index)
    return ground_section(rows, spec.ground_height()) if spec.space3d is not None and not team.flying else rows


def team_violation(team: TeamSpec, cells: Cells, starts: np.ndarray) -> np.ndarray:
    """Per robot, by how much its start violates its cell (``max(A p − b)`` over valid rows; ≤ 0 inside)."""
    points = starts[:, : cells.A.shape[2]]
    slack = np.einsum("nmd,nd->nm", cells.A, points) - cells.b
    return np.where(cells.valid, slack, -np.inf).max(axis=1, initial=-np.inf)


def controllers_keep_cells(spec: Spec) -> Guarantee:
    """Whether every team's controller keeps its robots inside their (convex) cells over a whole step."""
    reference = "Sec. 5: controllers constrained to the B-UAVC"
    if spec.method == "orca":
        return Guarantee("controllers provably keep every robot inside its cell", reference, False, detail="ORCA builds no cells")
    kinds = [(t.name or f"team {k}", (t.model.kind, t.model.controller)) for k, t in enumerate(spec.team_specs())]
    failing = [f"{name}: {LEAVES_CELL[kind]}" for name, kind in kinds if kind not in KEEPS_CELL]
    reasons = sorted({KEEPS_CELL[kind] for _, kind in kinds if kind in KEEPS_CELL})
    return Guarantee("controllers provably keep every robot inside its cell", reference, not failing,
                     detail="; ".join(failing), consequence="; ".join(reasons))


def per_step_bound(spec: Spec, premises: list[Guarantee]) -> Guarantee:
    """The bound that follows when every premise holds: collision probability ≤ δ per
    robot pair and per robot–obstacle pair at every step (with its constants)."""
    n = sum(t.n for t in spec.team_specs())
    n_obstacles = len(spec.space3d.boxes) if spec.space3d is not None else len(spec.workspace.obstacles)
    pairs, obstacle_pairs = n * (n - 1) // 2, n * n_obstacles
    setup = method_setup("buavc", spec.delta, spec.inflation_sigmas)
    team_bound = spec.delta * (pairs + obstacle_pairs)
    union = f"; whole team per step (union bound) ≤ {team_bound:.3g}" if team_bound < 1 else ""
    failed = [g.name for g in premises if not g.holds]
    return Guarantee(
        "collision probability ≤ δ per pair and step", "Sec. 4 (chance constraint); appendix A (Lemma 1, Theorem 1)", not failed,
        detail="not guaranteed, unmet: " + "; ".join(failed),
        consequence=(f"Pr(collision) ≤ δ = {spec.delta:g} for each of the {pairs} robot pairs and {obstacle_pairs} robot–obstacle pairs "
                     f"at every step (Φ⁻¹(√(1 − δ)) = {setup.quantile:.3f}, ε = {setup.epsilon:.4f}){union}"))
