"""Buffered uncertainty-aware Voronoi cells (Zhu et al. 2022, Sec. "B-UAVC"; docs/theory/buavc.md "Cell").

``V_i = {p : a_ijᵀp ≤ b_ij − ρ_ij − β_ij ∀ neighbours j;  a_ioᵀp ≤ b_io − r_i − β_io ∀ obstacles o;
walls tightened like obstacles}``, recomputed every control step from the current
estimates, with only the neighbours and obstacles inside robot i's local box
``p̂_i ± R_loc`` taken into account; ``β = Φ⁻¹(√(1 − δ)) √(aᵀΣ_i a)`` is robot i's own
chance buffer (:mod:`.buffer`) and ``ρ_ij = (r_i + r_j)/2`` the pair's mean radius.

Pairs of robots (any radii, any covariances)
    For the pair (i, j) both robots compute the same separating plane ``aᵀx = b``
    (appendix B; ``a`` a unit normal from i towards j). Robot i keeps
    ``aᵀx ≤ b − ρ_ij − q √(aᵀΣ_i a)`` and robot j keeps ``−aᵀx ≤ −b − ρ_ij − q √(aᵀΣ_j a)``,
    ``q = Φ⁻¹(√(1 − δ))``: the same ``ρ_ij`` on both sides, each robot its own Σ.
    (Equivalently: the plane moved ``(r_j − r_i)/2`` towards robot i, each robot keeping
    its own radius from it.)

    *Exact estimates* (Σ = 0). When both robots end a step in their cells, the two rows
    add to ``aᵀ(p_j − p_i) ≥ 2ρ_ij = r_i + r_j``, so ``‖p_j − p_i‖ ≥ r_i + r_j``. More holds:
    pair distances ``≥ r_i + r_j`` are an invariant of every closed loop in which each robot
    either holds still or ends its step on the segment from its position to a point of
    its cell (the safety filter, the one-step controller) — even when a cell is empty or a
    wall blocks a robot. With Σ = 0 the plane is the perpendicular bisector
    (``a = (p_j − p_i)/‖p_j − p_i‖``, ``b = aᵀ(p_i + p_j)/2``), so robot j at rest satisfies its
    row, ``−aᵀp_j = −b − ‖p_j − p_i‖/2 ≤ −b − ρ_ij``, whenever ``‖p_j − p_i‖ ≥ 2ρ_ij``; a row
    is a half-space, so every point of a segment from ``p_j`` to a point of the cell
    satisfies it too; the two rows give the bound at the next step. The mean is the only
    split of ``r_i + r_j`` with this property (robot j at rest needs its share
    ``≤ ‖p_j − p_i‖/2`` for every distance ``≥ r_i + r_j``, and so does robot i). Each robot
    keeping its own radius from the bisector loses it: a small robot driving at a large one
    held at a wall ends ``2 r_i`` from it, not ``r_i + r_j``.

    *The plane's offset.* For equal covariances (and Σ = 0) it is the midpoint,
    ``b = aᵀ(p̂_i + p̂_j)/2``. For unequal ones appendix B's minimax plane equalises the
    misclassification of the two *centres*: ``b_B = aᵀp̂_i + σ_i D/(σ_i + σ_j)`` with
    ``D = aᵀ(p̂_j − p̂_i)`` and ``σ = √(aᵀΣa)``. For discs that leaves the better-localised
    robot (σ_i < σ_j) outside its own cell whenever the pair is as close as the buffers
    allow (``b_B − aᵀp̂_i < ρ_ij + qσ_i`` at ``D = 2ρ_ij + q(σ_i + σ_j)``): the premise fails
    exactly when it matters (two robots of radius 0.2 m with σ 0.03 and 0.1 m driven
    head-on, δ = 0.1: 16 % of their close steps touched). The offset is therefore equalised for the discs,
    each Gaussian moved by ``ρ_ij`` towards the other:
    ``b = aᵀp̂_i + ρ_ij + σ_i (D − 2ρ_ij)/(σ_i + σ_j) = b_B + ρ_ij (σ_j − σ_i)/(σ_i + σ_j)``
    (:func:`disc_offsets`; reciprocal, the midpoint again for equal σ). Robot i's row then
    holds at its estimate iff ``σ_i ((D − 2ρ_ij)/(σ_i + σ_j) − q) ≥ 0``: both estimates lie
    in their cells exactly when ``D ≥ 2ρ_ij + q(σ_i + σ_j)``.

    *Chance constraint* (Sec. 4, unequal radii and covariances). Let robot i's true
    position be ``N(p̂_i, Σ_i)`` with ``p̂_i`` in its cell, independent of robot j's. Then
    ``aᵀp_i ~ N(aᵀp̂_i, σ_i²)``, ``σ_i = √(aᵀΣ_i a)``, and ``aᵀp̂_i ≤ b − ρ_ij − q σ_i``, so
    ``Pr(aᵀp_i ≤ b − ρ_ij) ≥ Φ(q) = √(1 − δ)`` (1 when σ_i = 0); likewise
    ``Pr(aᵀp_j ≥ b + ρ_ij) ≥ √(1 − δ)``. By independence both hold with probability
    ``≥ 1 − δ``, and then ``aᵀ(p_j − p_i) ≥ r_i + r_j``. Hence
    ``Pr(‖p_i − p_j‖ < r_i + r_j) ≤ δ`` per pair and step, for any radii, any Σ_i and Σ_j
    and any plane both robots compute alike. Obstacles and walls keep the robot's own
    ``r_i`` (the obstacle bound of appendix A is per robot).

Cells of all robots are stored as padded half-space arrays (:class:`Cells`), each robot's
rows in the order neighbours (by index), obstacles, walls. When all robots share one Σ in
the plane, a compiled kernel builds each robot's rows from its own view, robots in
parallel; robot j's plane for a pair is then exactly ``(−a, −b)`` of robot i's (appendix
B). Otherwise (or when the estimates spread too far for the uniform grid) the builder
evaluates each unordered pair once and gives robot j the reciprocal plane.
:func:`cell_from_view` builds one robot's cell from its local view alone and is the
reference the tests compare the batch against: the same rows.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from enum import IntEnum

import numba
import numpy as np
from scipy.spatial import cKDTree

from ..core.errors import ConfigError, short_repr
from .buffer import buffer
from .kernels import reused_array, use_parallel, work_array
from .neighbours import (
    box_gather,
    box_neighbours,
    column_runs,
    insertion_sort,
    sort_by_cell,
)
from .obstacles import ObstacleSet, obstacle_planes
from .separator import (
    separator_flat,
    separator_mode,
    shared_covariance_separator,
    shared_separator_row,
)


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
        """Whether each robot's point ``(N, d)`` lies in its own cell (padding rows hold)."""
        if self.A.shape[-1] != 2:
            return np.all(np.matmul(self.A, points[..., None])[..., 0] <= self.b + tol, axis=1)
        inside = np.empty(len(points), np.bool_)
        args = (np.ascontiguousarray(self.A), np.ascontiguousarray(self.b), np.ascontiguousarray(points, dtype=np.float64), float(tol), inside)
        if use_parallel(len(points)):
            _contains_parallel(*args)
        else:
            _contains_2d(0, len(points), *args)
        return inside

    def robot(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """``(A, b)`` of robot i's valid constraints."""
        keep = self.valid[i]
        return self.A[i, keep], self.b[i, keep]


@numba.njit(cache=True, parallel=True)
def _contains_parallel(A, b, points, tol, inside):
    n, chunk = len(points), 16 * _CHUNK
    for c in numba.prange((n + chunk - 1) // chunk):
        _contains_2d(c * chunk, min(n, (c + 1) * chunk), A, b, points, tol, inside)


@numba.njit(cache=True)
def _contains_2d(lo, hi, A, b, points, tol, inside):
    """:meth:`Cells.contains` of robots ``lo … hi − 1`` in the plane."""
    for i in range(lo, hi):
        inside[i] = True
        for k in range(A.shape[1]):
            if not A[i, k, 0] * points[i, 0] + A[i, k, 1] * points[i, 1] <= b[i, k] + tol:
                inside[i] = False
                break


@dataclass(frozen=True)
class CellGeometry:
    """Static data every robot knows: obstacles (with shadows) and workspace walls."""

    obstacles: ObstacleSet
    wall_a: np.ndarray
    wall_b: np.ndarray


def neighbour_pairs(estimates: np.ndarray, local_box: float) -> np.ndarray:
    """Unordered pairs ``(i, j)``, ``i < j``, inside each other's local box ``|p̂_i − p̂_j|_∞ ≤ R_loc``
    (2-D: uniform grid, sorted by ``(i, j)``; 3-D: k-d tree)."""
    if len(estimates) < 2:
        return np.empty((0, 2), dtype=np.intp)
    if estimates.shape[1] == 2 and grid_fits(estimates, local_box):
        start, index = box_neighbours(estimates, local_box)
        owner = np.repeat(np.arange(len(estimates), dtype=np.intp), np.diff(start))
        keep = owner < index
        return np.column_stack([owner[keep], index[keep].astype(np.intp)])
    return cKDTree(estimates).query_pairs(local_box, p=np.inf, output_type="ndarray").reshape(-1, 2)


GRID_CELLS_MAX = 2.0**62
"""Most cells the uniform grid of :mod:`robofleet.avoidance.neighbours` may span (its integer cell keys are
``c_x · rows + c_y``); estimates spread wider (``1e20`` m apart) use a k-d tree."""


def grid_fits(estimates: np.ndarray, local_box: float) -> bool:
    """Whether the estimates' bounding box spans fewer than :data:`GRID_CELLS_MAX` grid cells of side R_loc
    (the extent taken along contiguous rows of the transposed estimates: numpy's reduction
    over the first axis of ``(N, 2)`` took 40 times as long, for the same maxima and minima)."""
    with np.errstate(over="ignore"):
        span = np.ptp(np.ascontiguousarray(estimates.T), axis=1) / local_box + 1.0
    return bool(np.prod(span) < GRID_CELLS_MAX)


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
    radius: ``(N,)`` safety radii r_i, one per robot (inflated for the inflated-BVC
        baseline); a pair keeps ``r_i + r_j`` (module docstring).
    quantile: ``Φ⁻¹(√(1 − δ))``.
    geometry: obstacles and walls.
    local_box: R_loc, half-width of the local box.

    Notes
    -----
    In the plane with one Σ shared by all robots (the authors' setup) every robot's rows
    come from one compiled kernel, robots in parallel (:func:`_shared_cells_2d`);
    otherwise pairs are evaluated once each and scattered (appendix B reciprocity).
    The cost is O(N + K) for K neighbour pairs (a uniform grid, :mod:`robofleet.avoidance.neighbours`; a
    k-d tree in 3-D), plus O(N · O_loc · V) for the obstacles within R_loc (:meth:`.obstacles.ObstacleSet.near`).
    """
    check_cell_inputs(estimates, covs, radius, geometry)
    n, d = estimates.shape
    obstacles = _obstacle_rows(estimates, covs, radius, quantile, geometry.obstacles, local_box)
    if d == 2 and n > 0 and _uniform(covs) and grid_fits(estimates, local_box):
        return _shared_cells_2d(estimates, covs[0], radius, quantile, geometry, obstacles, local_box)
    pairs = neighbour_pairs(estimates, local_box)
    parts = [_robot_rows(estimates, covs, radius, quantile, pairs), obstacles,
             _wall_rows(estimates, covs, radius, quantile, geometry, local_box)]
    return _pad(n, d, parts)


def _shared_cells_2d(p, cov, radius, quantile, geometry: CellGeometry, obstacles, local_box) -> Cells:
    """Cells of 2-D robots sharing Σ, one compiled pass per robot.

    Robot i's rows, in increasing neighbour index, are ``a = Σ⁻¹(p̂_j − p̂_i)/‖·‖``,
    ``b = aᵀ(p̂_i + p̂_j)/2 − β − ρ_ij`` (:func:`~.separator.shared_separator_row`: Eqs.
    (48)–(50) with t = ½; ``ρ_ij = (r_i + r_j)/2``), then its obstacle rows, then its wall
    rows (walls within R_loc, ``b_w − β(a_w) − r_i``). Robot j computes exactly ``(−a, −b)``
    for the same pair (the formulas are odd in ``p̂_j − p̂_i`` and symmetric in ``p̂_i + p̂_j``), so each
    robot's rows come from its own view: a first pass gathers every robot's neighbours
    (sizing the padded arrays), a second writes every robot's rows once, robots in
    parallel (:mod:`.kernels`).
    """
    n = len(p)
    p = np.ascontiguousarray(p, dtype=np.float64)
    grid = (local_box, *sort_by_cell(p, local_box))
    wall_a = np.ascontiguousarray(geometry.wall_a, dtype=np.float64).reshape(-1, 2)
    wall_b = np.ascontiguousarray(geometry.wall_b, dtype=np.float64).reshape(-1)
    wall_spread = quantile * np.sqrt(np.maximum(_quad_2d(wall_a, cov), 0.0))  # β − r_s of each wall row, as buffer()
    o_start, o_a, o_b, o_src = _by_owner(n, obstacles)
    count, walls, near = _gather(grid, wall_a, wall_b, n, use_parallel(n))
    mode, solve = _shared_mode(np.asarray(cov, dtype=np.float64), int(count.sum()) // 2)
    m = max(int((count + np.diff(o_start) + walls).max(initial=0)), 1)
    A, b = reused_array("cell.A", (n, m, 2), np.float64), reused_array("cell.b", (n, m), np.float64)
    valid, kinds = reused_array("cell.valid", (n, m), np.bool_), reused_array("cell.kind", (n, m), np.int8)
    src = reused_array("cell.source", (n, m), np.intp)
    c = np.asarray(cov, dtype=np.float64)
    args = (p, near, count, mode, solve, c[0, 0], c[0, 1], c[1, 1], float(quantile), np.ascontiguousarray(radius, dtype=np.float64),
            o_start, o_a, o_b, o_src, wall_a, wall_b, wall_spread, local_box, A, b, valid, kinds, src)
    if use_parallel(n):
        _fill_parallel(*args)
    else:
        _fill_rows(0, n, *args)
    return Cells(A, b, valid, kinds, src)


def _shared_mode(cov: np.ndarray, pairs: int) -> tuple[int, np.ndarray]:
    """:func:`~.separator.separator_mode` of the shared Σ, remembered for the same Σ (and
    whether there is one pair): Σ is fixed in most runs, and preparing it is numpy work on
    a 2 × 2 matrix every step (a copy of the remembered array is returned)."""
    mode, solve = _mode_of(cov.tobytes(), pairs == 1)
    return mode, solve.copy()


@functools.lru_cache(maxsize=16)
def _mode_of(cov_bytes: bytes, one_pair: bool) -> tuple[int, np.ndarray]:
    return separator_mode(np.frombuffer(cov_bytes, dtype=np.float64).reshape(2, 2), pairs=1 if one_pair else 2)


def _quad_2d(normals: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """``aᵀΣa`` of unit normals ``(K, 2)``, rounded exactly as :func:`~.buffer.buffer` does."""
    return normals[:, 0] * (cov[0, 0] * normals[:, 0] + 2 * cov[0, 1] * normals[:, 1]) + cov[1, 1] * normals[:, 1] ** 2


@numba.njit(cache=True, inline="always")
def face_excess(A, b, i, k, x0, x1):
    """How far the point ``(x0, x1)`` lies beyond row ``k`` of robot ``i``'s cell,
    ``(aₖ·x − bₖ)/max(‖aₖ‖, 1e-12)`` (negative inside), rounded as the numpy expressions
    ``einsum(A, x) − b`` and ``np.maximum(np.linalg.norm(A), 1e-12)`` round it."""
    a0, a1 = A[i, k, 0], A[i, k, 1]
    norm = np.sqrt(a0 * a0 + a1 * a1)
    return ((a0 * x0 + a1 * x1) - b[i, k]) / (norm if norm != norm or norm > 1e-12 else 1e-12)


@numba.njit(cache=True, inline="always")
def _near_wall(x, y, wall_a, wall_b, w, r):
    """Wall w is within R_loc of the point (:func:`_wall_rows`' test ``b_w − a_w·p ≤ R_loc``)."""
    return wall_b[w] - (wall_a[w, 0] * x + wall_a[w, 1] * y) <= r


def _by_owner(n: int, rows):
    """Obstacle rows ``(owner, a, b, kind, source)`` (owner-major, as :func:`_obstacle_rows`
    makes them) as CSR by owner."""
    start = np.zeros(n + 1, np.int64)
    if rows is None or len(rows[0]) == 0:
        return start, np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.intp)
    np.cumsum(np.bincount(rows[0], minlength=n), out=start[1:])
    return start, np.ascontiguousarray(rows[1], dtype=np.float64), np.ascontiguousarray(rows[2], dtype=np.float64), rows[4].astype(np.intp)


_CHUNK = 64  # grid cells (or robots, × 4 or × 16) per parallel task
_NEAR = 16  # neighbours kept per robot by the gathering pass (more: a second, wider pass)


def _gather(grid, wall_a, wall_b, n, parallel):
    """Every robot's box neighbours, sorted, into ``near (N, width)``, their ``count`` and
    the number of walls within R_loc; ``width`` is 16 unless a robot has more."""
    count, walls = np.empty(n, np.int64), np.empty(n, np.int64)
    width = _NEAR
    while True:
        near = work_array("cell.near", (n, width), np.int32 if n < 2**31 else np.int64)  # read by the filling pass only
        if parallel:
            _gather_parallel(*grid, wall_a, wall_b, near, count, walls)
        else:
            _gather_cells(0, len(grid[3]) - 1, *grid, wall_a, wall_b, near, count, walls)
        most = int(count.max(initial=0))
        if most <= width:
            return count, walls, near
        width = most


@numba.njit(cache=True, parallel=True)
def _gather_parallel(r, rows, cell_key, cstart, order, spts, wall_a, wall_b, near, count, walls):
    cells = len(cstart) - 1
    for c in numba.prange((cells + _CHUNK - 1) // _CHUNK):
        _gather_cells(c * _CHUNK, min(cells, (c + 1) * _CHUNK), r, rows, cell_key, cstart, order, spts, wall_a, wall_b, near, count, walls)


@numba.njit(cache=True)
def _gather_cells(lo, hi, r, rows, cell_key, cstart, order, spts, wall_a, wall_b, near, count, walls):
    """Robots of grid cells ``lo … hi − 1``: box neighbours (sorted into ``near[i]`` when
    they fit), their count, and the walls within R_loc."""
    runs, cursor = np.empty(6, np.int64), np.empty(6, np.int64)
    buf = np.empty(near.shape[1], np.int64)
    for c in range(lo, hi):
        column_runs(c, rows, cell_key, cstart, cursor, c == lo, runs)
        for m in range(cstart[c], cstart[c + 1]):
            i = order[m]
            k = box_gather(m, r, runs, order, spts, buf)
            count[i] = k
            if k <= len(buf):
                insertion_sort(buf[:k])
                for t in range(k):
                    near[i, t] = buf[t]
            walls[i] = 0
            for w in range(len(wall_b)):
                walls[i] += _near_wall(spts[m, 0], spts[m, 1], wall_a, wall_b, w, r)


@numba.njit(cache=True, parallel=True)
def _fill_parallel(p, near, count, mode, solve, c00, c01, c11, quantile, radius, o_start, o_a, o_b, o_src, wall_a, wall_b, wall_spread, r,
                   A, b, valid, kinds, src):
    n, chunk = len(p), 4 * _CHUNK
    for c in numba.prange((n + chunk - 1) // chunk):
        _fill_rows(c * chunk, min(n, (c + 1) * chunk), p, near, count, mode, solve, c00, c01, c11, quantile, radius,
                   o_start, o_a, o_b, o_src, wall_a, wall_b, wall_spread, r, A, b, valid, kinds, src)


@numba.njit(cache=True)
def _fill_rows(lo, hi, p, near, count, mode, solve, c00, c01, c11, quantile, radius, o_start, o_a, o_b, o_src, wall_a, wall_b, wall_spread, r,
               A, b, valid, kinds, src):
    """Padded rows of robots ``lo … hi − 1`` (see :func:`_shared_cells_2d`)."""
    for i in range(lo, hi):
        x, y = p[i, 0], p[i, 1]
        for t in range(count[i]):
            j = near[i, t]
            a0, a1, off = shared_separator_row(x, y, p[j, 0], p[j, 1], mode, solve)
            quad = a0 * (c00 * a0 + 2 * c01 * a1) + c11 * (a1 * a1)  # aᵀΣa, as buffer.buffer
            pair_radius = 0.5 * (radius[i] + radius[j])  # ρ_ij, the same for robot j (module docstring)
            _put(A, b, valid, kinds, src, i, t, a0, a1, (off - (0.0 + quantile * np.sqrt(max(quad, 0.0)))) - pair_radius, 0, j)
        t = count[i]
        for e in range(o_start[i], o_start[i + 1]):
            _put(A, b, valid, kinds, src, i, t, o_a[e, 0], o_a[e, 1], o_b[e], 1, o_src[e])
            t += 1
        for w in range(len(wall_b)):
            if _near_wall(x, y, wall_a, wall_b, w, r):
                _put(A, b, valid, kinds, src, i, t, wall_a[w, 0], wall_a[w, 1], wall_b[w] - (radius[i] + wall_spread[w]), 2, w)
                t += 1
        for pad in range(t, A.shape[1]):
            _put(A, b, valid, kinds, src, i, pad, 0.0, 0.0, 1.0, -1, -1)
            valid[i, pad] = False


@numba.njit(cache=True, inline="always")
def _put(A, b, valid, kinds, src, i, t, a0, a1, off, kind, source):
    A[i, t, 0], A[i, t, 1], b[i, t] = a0, a1, off
    valid[i, t], kinds[i, t], src[i, t] = True, kind, source


def _robot_rows(p, covs, radius, quantile, pairs):
    """Both robots' rows of every pair ``(i, j)``: the pair's plane, ``ρ_ij`` and each robot's
    own buffer (module docstring)."""
    i, j = pairs[:, 0], pairs[:, 1]
    owner = np.concatenate([i, j])
    pair_radius = 0.5 * (radius[i] + radius[j])  # ρ_ij on both sides
    if _uniform(covs):  # every robot has the same Σ: closed form (the midpoint plane), no per-pair gathers
        a, b = shared_covariance_separator(p[i], p[j], covs[0])
        spread = buffer(np.concatenate([a, -a]), covs[0], 0.0, quantile)
    else:
        a, b = separator_flat(p[i], covs[i], p[j], covs[j])
        b = disc_offsets(a, b, covs[i], covs[j], pair_radius)
        spread = buffer(np.concatenate([a, -a]), covs[owner], 0.0, quantile)
    offsets = np.concatenate([b, -b]) - spread - np.concatenate([pair_radius, pair_radius])
    return owner, np.concatenate([a, -a]), offsets, Kind.ROBOT, np.concatenate([j, i])


def disc_offsets(a: np.ndarray, b: np.ndarray, cov_i: np.ndarray, cov_j: np.ndarray, pair_radius: np.ndarray) -> np.ndarray:
    """Appendix B's offsets ``b`` (robot i's side ``aᵀx ≤ b``) moved so that the two robots'
    discs, not their centres, are misclassified alike: ``b + ρ_ij (σ_j − σ_i)/(σ_i + σ_j)``
    with ``σ = √(aᵀΣa)`` (module docstring, "The plane's offset"); unchanged for equal σ."""
    sigma_i, sigma_j = buffer(a, cov_i, 0.0, 1.0), buffer(a, cov_j, 0.0, 1.0)
    total = sigma_i + sigma_j
    return b + np.where(total > 0, pair_radius * (sigma_j - sigma_i) / np.where(total > 0, total, 1.0), 0.0)


def _uniform(covs: np.ndarray) -> bool:
    """Whether all robots share one covariance (a broadcast view or equal entries)."""
    return len(covs) > 0 and (covs.strides[0] == 0 or bool(np.all(covs == covs[0])))


def _obstacle_rows(p, covs, radius, quantile, obstacles: ObstacleSet, local_box):
    if obstacles.count == 0:
        return None
    owner, idx = obstacles.near(p, local_box)
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
    neighbour_radii: float | np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One robot's cell from its own local view only (reference for the batch builder).

    The view is what the robot sees: its estimate, covariance and radius, and the
    estimates, covariances and radii (``neighbour_radii``: one or one per neighbour;
    ``None``: the robot's own) of the neighbours inside its local box (others are ignored
    here too). Each neighbour row keeps the pair's mean radius ``(r_i + r_j)/2`` (module
    docstring). Returns ``(A, b, kind)`` of the valid constraints.
    """
    p = np.asarray(ego_estimate, float)
    nb = np.asarray(neighbour_estimates, float).reshape(-1, p.shape[0])
    ncov = np.asarray(neighbour_covs, float).reshape(-1, p.shape[0], p.shape[0])
    nradius = np.broadcast_to(np.asarray(ego_radius if neighbour_radii is None else neighbour_radii, float), (len(nb),))
    keep = np.all(np.abs(nb - p) <= local_box, axis=1)
    nb, ncov, nradius = nb[keep], ncov[keep], nradius[keep]
    rows_a, rows_b, kinds = [], [], []
    if len(nb):
        ego_covs = np.repeat(np.asarray(ego_cov, float)[None], len(nb), 0)
        a, b = separator_flat(np.repeat(p[None], len(nb), 0), ego_covs, nb, ncov)
        pair_radius = 0.5 * (ego_radius + nradius)
        b = disc_offsets(a, b, ego_covs, ncov, pair_radius)
        rows_a.append(a), rows_b.append(b - buffer(a, ego_cov, 0.0, quantile) - pair_radius), kinds.append(np.full(len(a), Kind.ROBOT))
    ego, ego_covs, ego_radii = p[None], np.asarray(ego_cov, float)[None], np.array([ego_radius])
    for rows in (_obstacle_rows(ego, ego_covs, ego_radii, quantile, geometry.obstacles, local_box),
                 _wall_rows(ego, ego_covs, ego_radii, quantile, geometry, local_box)):
        if rows is not None and len(rows[0]):
            rows_a.append(rows[1]), rows_b.append(rows[2]), kinds.append(np.full(len(rows[0]), rows[3]))
    if not rows_a:
        return np.zeros((0, p.shape[0])), np.zeros(0), np.zeros(0, int)
    return np.concatenate(rows_a), np.concatenate(rows_b), np.concatenate(kinds)


# -- input validation of build_cells (shapes and types only: O(1), it runs every step) --------
def check_cell_inputs(estimates: object, covs: object, radius: object, geometry: object) -> None:
    """One-line :class:`~robofleet.core.errors.ConfigError` s for arguments of the wrong kind or shape."""
    if not isinstance(estimates, np.ndarray) or estimates.ndim != 2 or estimates.shape[1] not in (2, 3):
        raise ConfigError(f"estimates: expected an array (N, 2) or (N, 3), received {short_repr(estimates)}")
    n, d = estimates.shape
    if not isinstance(covs, np.ndarray) or covs.shape != (n, d, d):
        raise ConfigError(f"covs: expected an array ({n}, {d}, {d}), received shape {np.shape(covs)}")
    if np.shape(radius) != (n,):
        raise ConfigError(f"radius: expected an array ({n},), received shape {np.shape(radius)}")
    if not isinstance(geometry, CellGeometry):
        raise ConfigError(f"geometry: expected a CellGeometry, received {type(geometry).__name__}")


def cell_rows(cells: Cells, rows: np.ndarray | slice) -> Cells:
    """The cells of some robots only (an index array or a slice of the fleet)."""
    return Cells(cells.A[rows], cells.b[rows], cells.valid[rows], cells.kind[rows], cells.source[rows])
