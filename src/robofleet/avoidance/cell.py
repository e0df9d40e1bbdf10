"""Buffered uncertainty-aware Voronoi cells (Zhu et al. 2022, Sec. "B-UAVC"; notes/buavc.md "Cell").

``V_i = {p : a_ijᵀp ≤ b_ij − β_ij ∀ neighbours j;  a_ioᵀp ≤ b_io − β_io ∀ obstacles o;
walls tightened the same way}``, recomputed every control step from the current
estimates, with only the neighbours and obstacles inside robot i's local box
``p̂_i ± R_loc`` taken into account.

Cells of all robots are stored as padded half-space arrays (:class:`Cells`). The batch
builder evaluates each unordered robot pair once and gives robot j the reciprocal plane
``(−a, −b)`` (appendix B), which is exactly what j computes from its own view;
:func:`cell_from_view` builds one robot's cell from its local view alone and is the
reference the tests compare the batch against.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numba
import numpy as np
from scipy.spatial import cKDTree

from .buffer import buffer
from .obstacles import ObstacleSet, obstacle_planes
from .separator import separator_flat, shared_covariance_separator


class Kind(IntEnum):
    """What produced a cell constraint (used by the deadlock heuristic of appendix C)."""

    ROBOT = 0
    OBSTACLE = 1
    WALL = 2


@dataclass(frozen=True)
class Cells:
    """Cells of N robots as padded half-spaces: robot i's cell is ``{p : A[i,m]·p ≤ b[i,m], valid[i,m]}``.

    ``kind[i, m]`` is a :class:`Kind`, ``source[i, m]`` the neighbour, obstacle or wall index.
    Invalid (padding) rows hold ``A = 0, b = 1`` so they are always satisfied.
    """

    A: np.ndarray
    b: np.ndarray
    valid: np.ndarray
    kind: np.ndarray
    source: np.ndarray

    def contains(self, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Whether each robot's point ``(N, d)`` lies in its own cell."""
        return np.all(np.matmul(self.A, points[..., None])[..., 0] <= self.b + tol, axis=1)

    def robot(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """``(A, b)`` of robot i's valid constraints."""
        keep = self.valid[i]
        return self.A[i, keep], self.b[i, keep]


@dataclass(frozen=True)
class CellGeometry:
    """Static data every robot knows: obstacles (with shadows) and workspace walls."""

    obstacles: ObstacleSet
    wall_a: np.ndarray
    wall_b: np.ndarray


def neighbour_pairs(estimates: np.ndarray, local_box: float) -> np.ndarray:
    """Unordered pairs ``(i, j)``, ``i < j``, inside each other's local box ``|p̂_i − p̂_j|_∞ ≤ R_loc``."""
    if len(estimates) < 2:
        return np.empty((0, 2), dtype=np.intp)
    return cKDTree(estimates).query_pairs(local_box, p=np.inf, output_type="ndarray").reshape(-1, 2)


def build_cells(
    estimates: np.ndarray,
    covs: np.ndarray,
    radius: np.ndarray,
    quantile: float,
    geometry: CellGeometry,
    local_box: float,
) -> Cells:
    """B-UAVC of every robot from the current estimates.

    Parameters
    ----------
    estimates: ``(N, d)`` position estimates p̂.
    covs: ``(N, d, d)`` estimate covariances Σ (zeros for the deterministic BVC).
    radius: ``(N,)`` safety radii r_s (inflated for the inflated-BVC baseline).
    quantile: ``Φ⁻¹(√(1 − δ))``.
    geometry: obstacles and walls.
    local_box: R_loc, half-width of the local box.

    Complexity: O(N log N + K) for K neighbour pairs, plus O(N · O_loc · V) for obstacles.
    """
    n = len(estimates)
    pairs = neighbour_pairs(estimates, local_box)
    parts = [_robot_rows(estimates, covs, radius, quantile, pairs)]
    parts.append(_obstacle_rows(estimates, covs, radius, quantile, geometry.obstacles, local_box))
    parts.append(_wall_rows(estimates, covs, radius, quantile, geometry, local_box))
    return _pad(n, estimates.shape[1], parts)


def _robot_rows(p, covs, radius, quantile, pairs):
    i, j = pairs[:, 0], pairs[:, 1]
    owner = np.concatenate([i, j])
    if _uniform(covs):  # every robot has the same Σ: closed form, no per-pair gathers
        a, b = shared_covariance_separator(p[i], p[j], covs[0])
        normals = np.concatenate([a, -a])
        spread = buffer(normals, covs[0], 0.0, quantile)
    else:
        a, b = separator_flat(p[i], covs[i], p[j], covs[j])
        normals = np.concatenate([a, -a])
        spread = buffer(normals, covs[owner], 0.0, quantile)
    offsets = np.concatenate([b, -b]) - spread - radius[owner]
    return owner, normals, offsets, Kind.ROBOT, np.concatenate([j, i])


def _uniform(covs: np.ndarray) -> bool:
    """Whether all robots share one covariance (a broadcast view or equal entries)."""
    return len(covs) > 0 and (covs.strides[0] == 0 or bool(np.all(covs == covs[0])))


def _obstacle_rows(p, covs, radius, quantile, obstacles: ObstacleSet, local_box):
    if obstacles.count == 0:
        return None
    near = np.all(p[:, None] + local_box >= obstacles.lo[None], axis=-1) & np.all(p[:, None] - local_box <= obstacles.hi[None], axis=-1)
    owner, idx = np.nonzero(near)
    a, b = obstacle_planes(p[owner], obstacles, idx)
    return owner, a, b - buffer(a, covs[owner], radius[owner], quantile), Kind.OBSTACLE, idx


def _wall_rows(p, covs, radius, quantile, geometry: CellGeometry, local_box):
    if len(geometry.wall_a) == 0:
        return None
    gap = geometry.wall_b[None] - p @ geometry.wall_a.T  # (N, W) distance to each wall line
    owner, idx = np.nonzero(gap <= local_box)
    a = geometry.wall_a[idx]
    return owner, a, geometry.wall_b[idx] - buffer(a, covs[owner], radius[owner], quantile), Kind.WALL, idx


def _pad(n: int, d: int, parts) -> Cells:
    """Group constraint rows by owner into padded per-robot arrays (O(K), no sort)."""
    parts = [pt for pt in parts if pt is not None]
    owner = np.concatenate([pt[0] for pt in parts]).astype(np.intp)
    normals = np.concatenate([pt[1] for pt in parts])
    offsets = np.concatenate([pt[2] for pt in parts])
    kind = np.concatenate([np.full(len(pt[0]), int(pt[3]), np.int8) for pt in parts])
    source = np.concatenate([pt[4] for pt in parts]).astype(np.intp)
    m = max(int(np.bincount(owner, minlength=n).max(initial=0)), 1)
    A = np.zeros((n, m, d))
    b = np.ones((n, m))
    valid = np.zeros((n, m), np.bool_)
    kinds = np.full((n, m), -1, np.int8)
    src = np.full((n, m), -1, np.intp)
    _scatter_rows(owner, np.ascontiguousarray(normals), offsets, kind, source, A, b, valid, kinds, src)
    return Cells(A, b, valid, kinds, src)


@numba.njit(cache=True)
def _scatter_rows(owner, normals, offsets, kind, source, A, b, valid, kinds, src):
    """Append row k to robot ``owner[k]``'s next free slot, keeping the input order."""
    fill = np.zeros(A.shape[0], np.intp)
    for k in range(len(owner)):
        i = owner[k]
        r = fill[i]
        fill[i] = r + 1
        for c in range(A.shape[2]):
            A[i, r, c] = normals[k, c]
        b[i, r] = offsets[k]
        valid[i, r] = True
        kinds[i, r] = kind[k]
        src[i, r] = source[k]


def cell_from_view(
    ego_estimate: np.ndarray,
    ego_cov: np.ndarray,
    ego_radius: float,
    neighbour_estimates: np.ndarray,
    neighbour_covs: np.ndarray,
    quantile: float,
    geometry: CellGeometry,
    local_box: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One robot's cell from its own local view only (reference for the batch builder).

    The view is what the robot sees: its estimate and covariance, and the estimates and
    covariances of the neighbours inside its local box (others are ignored here too).
    Returns ``(A, b, kind)`` of the valid constraints.
    """
    p = np.asarray(ego_estimate, float)
    nb = np.asarray(neighbour_estimates, float).reshape(-1, p.shape[0])
    ncov = np.asarray(neighbour_covs, float).reshape(-1, p.shape[0], p.shape[0])
    keep = np.all(np.abs(nb - p) <= local_box, axis=1)
    nb, ncov = nb[keep], ncov[keep]
    rows_a, rows_b, kinds = [], [], []
    if len(nb):
        a, b = separator_flat(np.repeat(p[None], len(nb), 0), np.repeat(ego_cov[None], len(nb), 0), nb, ncov)
        rows_a.append(a), rows_b.append(b - buffer(a, ego_cov, ego_radius, quantile)), kinds.append(np.full(len(a), Kind.ROBOT))
    ego, ego_covs, ego_radii = p[None], np.asarray(ego_cov, float)[None], np.array([ego_radius])
    for rows in (_obstacle_rows(ego, ego_covs, ego_radii, quantile, geometry.obstacles, local_box),
                 _wall_rows(ego, ego_covs, ego_radii, quantile, geometry, local_box)):
        if rows is not None and len(rows[0]):
            rows_a.append(rows[1]), rows_b.append(rows[2]), kinds.append(np.full(len(rows[0]), rows[3]))
    if not rows_a:
        return np.zeros((0, p.shape[0])), np.zeros(0), np.zeros(0, int)
    return np.concatenate(rows_a), np.concatenate(rows_b), np.concatenate(kinds)
