"""What every robot's B-UAVC is built from (Zhu et al. 2022, Sec. 4): the method's
ingredients, the fleet's noise, and the cells of the whole fleet.

Methods differ only in what the cells use (:class:`MethodSetup`):

* ``buavc``: Σ, Σ_o and the chance buffers (δ) — the B-UAVC of Sec. 4;
* ``bvc``: Σ = Σ_o = 0, buffer r_s (Zhou et al. 2017);
* ``bvc_inflated``: Σ = Σ_o = 0 and radius ``r_s + k σ_max`` (k = ``inflation_sigmas``);
* ``orca``: no cells (ORCA velocities with the obstacles and walls as RVO2 handles them,
  :mod:`.orca_obstacles`).

In a 3-D space every robot's cell is built in R³ from all estimates; ground robots
(every model but the quadrotor) move in the plane ``z = z_g`` (floor + r_s) and use their
cell's section with that plane (:func:`ground_section`). Their Σ has no z term, so the
planes between robots of such a fleet come from ``σ² I`` and only the buffers from Σ
(:func:`separator_covariances`); their route runs around the footprints of the boxes that
reach their plane (:func:`ground_footprints`). The loop (:mod:`robofleet.avoidance.simulation`), the safety
filter, the guarantees and the environment build their cells from here.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from shapely.geometry import Polygon

from ..core.geometry import box_vertices
from .buffer import buffer, confidence_quantile, shadow_epsilon
from .cell import CellGeometry, Cells, Kind, build_cells
from .cell3d import box_shadow_planes, project_onto_polytope, workspace_box_planes
from .obstacles import ObstacleSet, wall_planes
from .projection import project_onto_cells
from .segment_cells import with_braking_segments
from .spec import Space3DSpec, Spec, TeamSpec


# ---------------------------------------------------------------------------------------
# what a method's cells are made of
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MethodSetup:
    """What the cells of a method are built from (see the module docstring).

    Attributes
    ----------
    method: ``buavc``, ``bvc``, ``bvc_inflated`` or ``orca``.
    quantile: ``Φ⁻¹(√(1 − δ))`` of the chance buffer β (0 without chance constraint).
    epsilon: ε of the obstacles' ε-shadow, ``1 − √(1 − δ)`` (appendix A).
    inflation_sigmas: k of the inflated radius ``r_s + k σ_max`` (0 unless ``bvc_inflated``).
    """

    method: str
    quantile: float
    epsilon: float
    inflation_sigmas: float

    @property
    def chance_constrained(self) -> bool:
        """Whether the cells carry the chance constraint (Σ, Σ_o and δ enter them)."""
        return self.method == "buavc"

    def cell_covariance(self, cov: np.ndarray) -> np.ndarray:
        """The Σ a cell uses: the estimate's covariance for B-UAVC, zero for the BVC variants."""
        return cov if self.chance_constrained else np.zeros_like(cov)

    def cell_radius(self, radius: float, sigma: float) -> float:
        """The safety radius a cell uses: ``r_s``, or ``r_s + k σ_max`` for the inflated BVC."""
        return radius + self.inflation_sigmas * sigma


def method_setup(method: str, delta: float, inflation_sigmas: float) -> MethodSetup:
    """The cell ingredients of ``method`` at threshold ``delta`` (Sec. 4 and appendix A)."""
    if method == "buavc":
        return MethodSetup(method, confidence_quantile(delta), shadow_epsilon(delta), 0.0)
    return MethodSetup(method, 0.0, shadow_epsilon(delta), inflation_sigmas if method == "bvc_inflated" else 0.0)


def obstacle_set(polygons: list[np.ndarray], obstacle_cov: np.ndarray, setup: MethodSetup) -> ObstacleSet:
    """The 2-D obstacles a method's cells see: with their ε-shadows under Σ_o (appendix A,
    Lemma 1 and Theorem 1) for B-UAVC, nominal otherwise."""
    if setup.chance_constrained:
        return ObstacleSet.build(polygons, np.repeat(obstacle_cov[None], len(polygons), 0), setup.epsilon)
    return ObstacleSet.build(polygons, np.zeros((len(polygons), 2, 2)), 0.0)


def obstacle_clearance(radius: float, sigma: float, quantile: float, obstacles: ObstacleSet, obstacle_cov: np.ndarray) -> float:
    """Largest distance a cell keeps a robot from a nominal obstacle boundary: r_s + the
    chance buffer ``Φ⁻¹(√(1 − δ)) σ`` + the ε-shadow ``r_ε σ_o`` (used to place the detour
    vertices of appendix C)."""
    shadow = float(obstacles.shadow_radius.max(initial=0.0)) * float(np.sqrt(np.linalg.eigvalsh(obstacle_cov).max()))
    return radius + quantile * sigma + (shadow if np.isfinite(shadow) else 0.0)


def grown_obstacle_vertices(polygons: list[np.ndarray], margin: float) -> np.ndarray | None:
    """Vertices ``(O, V, 2)`` of the obstacles grown by ``margin`` (mitred, padded by
    repetition), the detour targets of the obstacle branch of appendix C."""
    grown = [Polygon(p).buffer(margin, join_style="mitre") for p in polygons]
    if not grown:
        return None
    verts = [np.asarray(p.exterior.coords)[:-1] for p in grown]
    v_max = max(len(v) for v in verts)
    return np.stack([np.vstack([v, np.repeat(v[-1:], v_max - len(v), 0)]) for v in verts])


def noise_factor(cov: np.ndarray) -> np.ndarray:
    """``L`` with ``L Lᵀ = Σ`` for any symmetric PSD ``Σ`` (Cholesky, eigen-factor if singular)."""
    if not np.any(cov):
        return np.zeros_like(cov)
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(cov)
        return v * np.sqrt(np.maximum(w, 0.0))


def team_noise_factor(team: TeamSpec, dim: int) -> np.ndarray:
    """``L`` with ``L Lᵀ`` = :func:`team_covariance` (3-D: ``σ diag(1, 1, 1 or 0)`` exactly)."""
    if dim == 2:
        cov = team.covariance()
        return noise_factor(cov) if cov.ndim == 2 else np.stack([noise_factor(c) for c in cov])
    return team.sigma * np.diag([1.0, 1.0, 1.0 if team.flying else 0.0])


def team_covariance(team: TeamSpec, dim: int) -> np.ndarray:
    """The ``(dim, dim)`` covariance of a team's position estimates: Σ in 2-D (``(n, 2, 2)``
    when its robots have their own); in 3-D
    ``σ² I`` for quadrotors and ``σ² diag(1, 1, 0)`` for ground robots (no z noise)."""
    if dim == 2:
        return team.covariance()
    return team.sigma**2 * np.diag([1.0, 1.0, 1.0 if team.flying else 0.0])


# ---------------------------------------------------------------------------------------
# the cells of the whole fleet
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BoxObstacles:
    """3-D box obstacles (yawed about z) with uncertain position ``N(0, cov)`` and the ε of their shadows."""

    centers: np.ndarray
    sizes: np.ndarray
    yaws: np.ndarray
    cov: np.ndarray
    epsilon: float

    @property
    def count(self) -> int:
        return len(self.centers)


@dataclass(frozen=True)
class CellModel:
    """What every robot's B-UAVC is built from (Sec. 4): each estimate's covariance Σ_i
    and safety radius, the buffer quantile, the walls and the obstacles with their
    shadows (2-D polygons in ``geometry``, 3-D boxes in ``boxes``), the local box R_loc.

    ``separator_covs`` (3-D teams with ground robots, :func:`separator_covariances`) are the
    covariances the pairwise separating planes are computed from when they differ from Σ_i;
    the buffers β always use Σ_i."""

    covs: np.ndarray
    radius: np.ndarray
    quantile: float
    geometry: CellGeometry
    local_box: float
    boxes: BoxObstacles | None = None
    separator_covs: np.ndarray | None = None

    def cells(self, estimates: np.ndarray, obstacle_shift: np.ndarray, stops: np.ndarray | None = None) -> Cells:
        """The cells of all robots from their estimates ``(N, d)`` and the obstacles'
        estimated displacements ``(O, d)``; with ``stops`` ``(N, d)``, the braking rule's
        stopping points, the rows of every robot whose stop differs from its estimate are
        built from the braking segments ``[p̂_i, stop_i]`` (:mod:`.segment_cells`)."""
        if self.boxes is None:
            geometry = replace(self.geometry, obstacles=shifted(self.geometry.obstacles, obstacle_shift))
            cells = build_cells(estimates, self.covs, self.radius, self.quantile, geometry, self.local_box)
            if stops is None:
                return cells
            return with_braking_segments(cells, estimates, stops, self.covs, self.radius, self.quantile, obstacles=geometry.obstacles)
        if self.separator_covs is None:
            cells = build_cells(estimates, self.covs, self.radius, self.quantile, self.geometry, self.local_box)
        else:
            cells = self.rebuffered(build_cells(estimates, self.separator_covs, self.radius, self.quantile, self.geometry, self.local_box))
        cells = cells if self.boxes.count == 0 else self.with_box_rows(cells, estimates, obstacle_shift)
        if stops is None:
            return cells
        b, sigma_o = self.boxes, float(np.sqrt(self.boxes.cov[0, 0]))  # Σ_o = σ_o² I in every 3-D scenario
        return with_braking_segments(cells, estimates, stops, self.covs, self.radius, self.quantile,
                                     boxes=(b.centers + obstacle_shift, b.sizes, b.yaws, sigma_o, b.epsilon))

    def rebuffered(self, cells: Cells) -> Cells:
        """``cells`` built with ``separator_covs``, their buffers replaced by those of Σ_i:
        ``b + q (√(aᵀ Σ_sep a) − √(aᵀ Σ_i a))`` (the planes stay, so the pair's two rows stay reciprocal)."""
        b = cells.b + buffer(cells.A, self.separator_covs[:, None], 0.0, self.quantile) - buffer(cells.A, self.covs[:, None], 0.0, self.quantile)
        return replace(cells, b=np.where(cells.valid, b, cells.b))

    def with_box_rows(self, cells: Cells, estimates: np.ndarray, shift: np.ndarray) -> Cells:
        """``cells`` plus one row per box inside each robot's local box: the max-margin plane
        to the box's ε-shadow (appendix A), tightened by the robot's buffer β."""
        boxes = self.boxes
        centers = boxes.centers + shift
        a, b = box_shadow_planes(estimates, centers, boxes.sizes, boxes.yaws, boxes.cov, boxes.epsilon)
        b = b - buffer(a, self.covs[:, None], self.radius[:, None], self.quantile)
        reach = 0.5 * np.linalg.norm(boxes.sizes, axis=1)
        near = np.all(np.abs(estimates[:, None] - centers[None]) <= self.local_box + reach[None, :, None], axis=-1)
        return Cells(np.concatenate([cells.A, a], 1), np.concatenate([cells.b, np.where(near, b, 1.0)], 1),
                     np.concatenate([cells.valid, near], 1),
                     np.concatenate([cells.kind, np.full(near.shape, int(Kind.OBSTACLE), np.int8)], 1),
                     np.concatenate([cells.source, np.broadcast_to(np.arange(boxes.count), near.shape)], 1))


def shifted(obstacles: ObstacleSet, shift: np.ndarray) -> ObstacleSet:
    """The obstacle set displaced by ``shift`` ``(O, d)`` (the obstacles' position estimates)."""
    if obstacles.count == 0:
        return obstacles
    return replace(obstacles, vertices=obstacles.vertices + shift[:, None], lo=obstacles.lo + shift, hi=obstacles.hi + shift)


def cell_model(spec: Spec, setup: MethodSetup) -> CellModel:
    """The :class:`CellModel` of a scenario under a method (one team: a broadcast Σ, so
    the separators take the shared-covariance closed form)."""
    teams, slices, dim = spec.team_specs(), spec.team_slices(), spec.dim
    n = slices[-1].stop
    if len(teams) == 1:  # one team: a broadcast Σ unless the robots have their own
        covs = np.broadcast_to(setup.cell_covariance(team_covariance(teams[0], dim)), (n, dim, dim))
    else:
        covs = np.empty((n, dim, dim))
        for team, sl in zip(teams, slices):
            covs[sl] = setup.cell_covariance(team_covariance(team, dim))
    radius = np.empty(n)
    for team, sl in zip(teams, slices):
        radius[sl] = setup.cell_radius(spec.robots.radius, team.largest_sigma())
    if spec.space3d is None:
        ws = spec.workspace
        geometry = CellGeometry(obstacle_set(ws.obstacle_polygons(), ws.obstacle_covariance(), setup), *wall_planes(ws.bounds_vertices()))
        return CellModel(covs, radius, setup.quantile, geometry, spec.local_box)
    space = spec.space3d
    no_polygons = ObstacleSet(np.zeros((0, 1, 3)), np.zeros((0, 3, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    geometry = CellGeometry(no_polygons, *workspace_box_planes(space.lower, space.upper))
    box_cov = setup.cell_covariance(space.obstacle_sigma**2 * np.eye(3))
    boxes = BoxObstacles(*space.box_arrays(), box_cov, setup.epsilon)
    return CellModel(covs, radius, setup.quantile, geometry, spec.local_box, boxes, separator_covariances(spec, setup, covs))


def separator_covariances(spec: Spec, setup: MethodSetup, covs: np.ndarray) -> np.ndarray | None:
    """The covariances the separating planes of a 3-D fleet with ground robots are computed
    from: ``σ² I`` for every robot (``None`` when every robot flies: Σ_i itself).

    A ground robot's Σ_i = σ² diag(1, 1, 0) is singular: its z is known exactly. Appendix B's
    minimax separator against a flying robot then tends to the horizontal plane through the
    ground robot's estimate (a horizontal normal misclassifies it with probability 0 at any
    offset), which leaves its section empty after the buffer r_s, however high the flying
    robot is. Any plane that both robots compute alike keeps the chance constraint (the
    argument of docs/theory/buavc.md "Buffer" holds for every plane once β uses the true Σ_i), so
    the plane is taken from ``σ² I`` — for equal σ the perpendicular bisector, the ordinary
    Voronoi face, which gives each robot half the distance — and β from Σ_i
    (:meth:`CellModel.rebuffered`)."""
    teams = spec.team_specs()
    if all(team.flying for team in teams):
        return None
    out = np.empty_like(covs)
    for team, sl in zip(teams, spec.team_slices()):
        out[sl] = setup.cell_covariance(team.sigma**2 * np.eye(3))
    return out


def ground_footprints(space: Space3DSpec, z: float, radius: float) -> list[np.ndarray]:
    """Footprints ``(4, 2)`` of the boxes of a 3-D space that a ground robot (a sphere of
    ``radius`` centred at height ``z``) can touch: the 2-D obstacles of ground teams."""
    centers, sizes, yaws = space.box_arrays()
    reach = np.abs(centers[:, 2] - z) < 0.5 * sizes[:, 2] + radius
    return [box_vertices(c, s, y) for c, s, y, r in zip(centers, sizes, yaws, reach) if r]


def ground_section(cells: Cells, z: float) -> Cells:
    """The section of 3-D cells with the plane ``z`` (ground robots), as 2-D cells:
    ``{(x, y) : a_xy·(x, y) ≤ b − a_z z}`` with rows normalised; rows with ``a_xy ≈ 0``
    are dropped when satisfied and make the cell empty otherwise, except the floor and
    ceiling walls, which do not bound ground robots."""
    a_xy = cells.A[..., :2]
    norm = np.linalg.norm(a_xy, axis=-1)
    b = cells.b - cells.A[..., 2] * z
    flat = norm < 1e-9
    keep = cells.valid & ~(flat & ((b >= 0) | (cells.kind == int(Kind.WALL))))
    A = np.where(flat[..., None], 0.0, a_xy / np.where(flat, 1.0, norm)[..., None])
    b = np.where(flat, np.where(b >= 0, 1.0, b), b / np.where(flat, 1.0, norm))
    return Cells(A, np.where(keep, b, 1.0), keep, cells.kind, cells.source)


def empty_cells(cells: Cells, points: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Which cells are empty: none that holds its robot's ``points`` (``inside``); the
    others by an exact projection onto the cell (2-D, :func:`project_onto_cells`; 3-D,
    :func:`~.cell3d.project_onto_polytope`), which reports infeasibility."""
    empty = np.zeros(len(points), bool)
    out = np.flatnonzero(~inside)
    if len(out) == 0:
        return empty
    A, b, valid = cells.A[out], cells.b[out], cells.valid[out]
    if points.shape[1] == 2:
        empty[out] = project_onto_cells(points[out], Cells(A, b, valid, cells.kind[out], cells.source[out])).empty
    else:
        empty[out] = ~project_onto_polytope(points[out], A, b, valid)[1]
    return empty
