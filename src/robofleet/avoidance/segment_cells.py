"""Cells built from the robots' braking segments (the condition of :mod:`.braking`).

A B-UAVC separates the robots' *points*. A double integrator under the braking rule needs
more: its whole braking segment ``S_i = [p̂_i, stop(p̂_i, v_i)]`` must lie in its cell, at
every step, although the cells are built anew from the new estimates each step
(:mod:`.braking` states the invariant and proves it). Here every cell row that concerns a
robot with a non-degenerate segment is rebuilt from the segments:

* **robot pair** ``(i, j)``: the maximum-margin plane between ``S_i`` and ``S_j`` — normal
  ``a = (c_j − c_i)/‖c_j − c_i‖`` along a closest pair ``(c_i, c_j)`` of the two segments
  (:func:`closest_points_between_segments`), through its midpoint
  (:func:`segment_separators`). For disjoint convex sets the plane orthogonal to a closest
  pair supports both: ``aᵀx ≤ aᵀc_i`` on ``S_i`` and ``aᵀx ≥ aᵀc_j`` on ``S_j``, so each
  segment lies ``‖c_j − c_i‖/2`` from the plane. Robot ``i``'s row is
  ``aᵀp ≤ aᵀ(c_i + c_j)/2 − (r_i + r_j)/2 − Φ⁻¹(√(1 − δ)) √(aᵀΣ_i a)`` and robot ``j``'s
  is exactly ``(−a, −b)`` with its own buffer: each unordered pair is evaluated once, in
  index order, so the two rows are reciprocal bit for bit. With ``Σ = 0``: if the segments
  are at least ``r_i + r_j`` apart, each lies in its row.
* **obstacle** ``o``: after whitening with ``W = Σ_o^{-1/2}`` (:mod:`.obstacles`, appendix
  A), the plane orthogonal to a closest pair between the whitened segment and the
  whitened polygon (2-D, :func:`segment_polygon_planes`) or box (3-D,
  :func:`segment_box_planes`), touching the ε-shadow, tightened by ``r_i`` and the chance
  buffer as a point's row. With ``Σ_o = 0`` (or ``σ_o² I``, a uniform scaling) it is the
  Euclidean maximum-margin plane: a segment at least ``r_i`` from the shadow lies in it.
* **walls** are fixed half-planes: nothing to rebuild (a segment lies in one when both
  ends do).

Rows of pairs where neither robot has a segment (single integrators, robots at rest,
every other model) keep the point separators of :mod:`.cell` (appendix B). A segment that
meets its neighbour's, or an obstacle's shadow, has no separating plane: its row keeps
the point separator and the segment does not lie in its cell (the premise of the
braking rule fails; the rule then brakes, see :mod:`.braking`).

Cost: ``O(K)`` for the ``K`` rows of moving robots, compiled one row at a time (pair rows
on numba's threads for large fleets, :mod:`.kernels`); no row of a fleet at rest is
touched. The rows are found through the cells' own ``kind``/``source``, so the neighbours
are those of the neighbour search of :func:`.cell.build_cells` (measured, 2000 double
integrators among 182 boxes: the cells take about a quarter longer than the point cells,
some 3 % of the whole step).
"""

from __future__ import annotations

from dataclasses import replace

import numba
import numpy as np

from .buffer import buffer
from .cell import Cells, Kind
from .cell3d import shadow_radius
from .kernels import use_parallel
from .obstacles import ObstacleSet

_SEPARATED = 1e-12
"""Smallest gap [m] between two convex sets for which a closest pair defines a plane."""
_GOLDEN_STEPS = 60
"""Golden-section steps for the segment–box distance (bracket shrinks to 0.618⁶⁰ ≈ 3e-13)."""


# ---------------------------------------------------------------------------------------
# closest points
# ---------------------------------------------------------------------------------------
def closest_points_between_segments(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A closest pair ``(c_p, c_q)`` between segments ``[p0, p1]`` and ``[q0, q1]`` (``(K, d)``, any d).

    The squared distance ``‖p0 + s d_p − q0 − t d_q‖²`` is a convex quadratic on the square
    ``[0, 1]²``: its minimum is the interior critical point when that exists and lies in the
    square, otherwise on an edge of the square — one end of one segment against the other
    segment. All five candidates are evaluated and the nearest wins (parallel and
    degenerate segments have no interior candidate and need none). Compiled, one pair at
    a time (:func:`_closest_pair`).
    """
    p0, p1, q0, q1 = (np.ascontiguousarray(x, dtype=np.float64) for x in (p0, p1, q0, q1))
    cp, cq = np.empty_like(p0), np.empty_like(p0)
    _closest_pairs(p0, p1, q0, q1, cp, cq)
    return cp, cq


def segment_separators(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Maximum-margin plane between segments ``[p0, p1]`` and ``[q0, q1]`` (``(K, d)``).

    Returns ``a (K, d)`` unit normals from the first segment towards the second,
    ``b (K,)`` with the first segment's side ``aᵀx ≤ b``, and the gap ``(K,)`` between
    the segments (each lies ``gap/2`` from the plane).
    """
    cp, cq = closest_points_between_segments(p0, p1, q0, q1)
    a, off, gap = np.zeros_like(cp), np.zeros(len(cp)), np.empty(len(cp))
    _separators(cp, cq, a, off, gap)
    return a, off, gap


@numba.njit(cache=True)
def _closest_pairs(p0, p1, q0, q1, cp, cq):
    for k in range(len(p0)):
        _closest_pair(p0[k], p1[k], q0[k], q1[k], cp[k], cq[k])


@numba.njit(cache=True)
def _separators(cp, cq, a, off, gap):
    for k in range(len(cp)):
        gap[k] = _plane(cp[k], cq[k], 1.0, a[k])
        off[k] = _midplane_offset(a[k], cp[k], cq[k])


@numba.njit(cache=True, inline="always")
def _midplane_offset(a, cp, cq):
    """``aᵀ(c_p + c_q)/2``: the offset of the plane with normal ``a`` through the pair's midpoint."""
    off = 0.0
    for m in range(len(a)):
        off += a[m] * (0.5 * (cp[m] + cq[m]))
    return off


@numba.njit(cache=True)
def _closest_pair(p0, p1, q0, q1, cp, cq):
    """Write a closest pair of segments ``[p0, p1]``, ``[q0, q1]`` into ``cp``, ``cq``
    (the five candidates of :func:`closest_points_between_segments`)."""
    d = len(p0)
    a = e = b = c = f = 0.0
    for k in range(d):
        dp, dq, r = p1[k] - p0[k], q1[k] - q0[k], p0[k] - q0[k]
        a += dp * dp
        e += dq * dq
        b += dp * dq
        c += dp * r
        f += dq * r
    cand = np.empty((5, 2))
    cand[0, 0], cand[0, 1] = _clamp01(-c, a), 0.0  # q0 against [p0, p1]
    cand[1, 0], cand[1, 1] = _clamp01(b - c, a), 1.0  # q1 against [p0, p1]
    cand[2, 0], cand[2, 1] = 0.0, _clamp01(f, e)  # p0 against [q0, q1]
    cand[3, 0], cand[3, 1] = 1.0, _clamp01(f + b, e)  # p1 against [q0, q1]
    count = 4
    det = a * e - b * b
    if det > 1e-12 * a * e and det > 0.0:
        s, t = (b * f - c * e) / det, (a * f - b * c) / det
        if 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0:
            cand[4, 0], cand[4, 1] = s, t
            count = 5
    best, best_gap = 0, np.inf
    for m in range(count):
        gap = 0.0
        for k in range(d):
            x = (p0[k] + cand[m, 0] * (p1[k] - p0[k])) - (q0[k] + cand[m, 1] * (q1[k] - q0[k]))
            gap += x * x
        if gap < best_gap:
            best, best_gap = m, gap
    for k in range(d):
        cp[k] = p0[k] + cand[best, 0] * (p1[k] - p0[k])
        cq[k] = q0[k] + cand[best, 1] * (q1[k] - q0[k])


@numba.njit(cache=True, inline="always")
def _clamp01(numerator, denominator):
    """``clip(numerator / denominator, 0, 1)``, 0 for a degenerate segment (``denominator = 0``)."""
    if denominator <= 0.0:
        return 0.0
    return min(max(numerator / denominator, 0.0), 1.0)


@numba.njit(cache=True)
def _plane(cp, cq, sign, a):
    """Write ``sign · (cq − cp)/‖cq − cp‖`` into ``a``; return the gap ``‖cq − cp‖``
    (``a`` untouched when it is not above :data:`_SEPARATED`)."""
    gap = 0.0
    for k in range(len(cp)):
        gap += (cq[k] - cp[k]) ** 2
    gap = np.sqrt(gap)
    if gap > _SEPARATED:
        for k in range(len(cp)):
            a[k] = sign * (cq[k] - cp[k]) / gap
    return gap


# ---------------------------------------------------------------------------------------
# obstacles
# ---------------------------------------------------------------------------------------
def segment_polygon_planes(start: np.ndarray, end: np.ndarray, obstacles: ObstacleSet, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robot-side half-planes ``aᵀp ≤ b`` between 2-D segments and obstacles' ε-shadows.

    Parameters
    ----------
    start, end : numpy.ndarray
        ``(R, 2)`` the segments, one row per (robot, obstacle) pair.
    obstacles : ObstacleSet
        The obstacles (whitening and shadow radius of appendix A).
    index : numpy.ndarray
        ``(R,)`` the obstacle of each row.

    Returns
    -------
    ``a (R, 2)`` unit normals, ``b (R,)`` before the robot's own buffer, and ``ok (R,)``:
    the whitened segment and polygon are disjoint (else ``a, b`` are meaningless).

    Notes
    -----
    In the plane, a closest pair between a segment and a disjoint convex polygon has an
    end of the segment or a vertex of the polygon in it: the candidates are both ends
    against every edge and every vertex against the segment (compiled, one row at a time,
    :func:`_polygon_plane`). The pair found is then checked to separate (every vertex on
    the polygon's side of the plane through it, both ends on the other): that fails
    exactly when the two meet.
    """
    a, b, ok = np.zeros((len(index), 2)), np.zeros(len(index)), np.zeros(len(index), np.bool_)
    _polygon_planes(np.ascontiguousarray(start, dtype=np.float64), np.ascontiguousarray(end, dtype=np.float64),
                    np.ascontiguousarray(obstacles.whitening), np.ascontiguousarray(obstacles.vertices, dtype=np.float64),
                    np.ascontiguousarray(obstacles.shadow_radius, dtype=np.float64), np.asarray(index, np.intp), a, b, ok)
    return a, b, ok


def segment_box_planes(start: np.ndarray, end: np.ndarray, centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray,
                       sigma: float, epsilon: float, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robot-side half-spaces ``aᵀp ≤ b`` between 3-D segments and the ε-shadows of boxes
    yawed about z whose position is uncertain with ``Σ_o = σ² I`` (every 3-D scenario's;
    the segment form of :func:`~.cell3d.box_shadow_planes`), one row per (segment, box)
    pair, ``index`` the box. Returns ``a (R, 3)``, ``b (R,)`` before the robot's buffer and
    ``ok (R,)`` (the segment misses the box).

    With ``Σ_o = σ² I`` whitening is a uniform scaling, so the shadow is the box grown by
    the ball of radius ``σ √(χ²₃⁻¹(1 − ε))`` (appendix A) and the maximum-margin plane is
    the one orthogonal to a closest pair of the segment and the box itself. In the box's
    frame the box is ``[−h, h]³`` and the nearest box point to ``x`` is ``clip(x, −h, h)``;
    the distance from ``s(t)`` to the box is convex in ``t``, so a golden-section search
    over ``t ∈ [0, 1]`` finds the segment's nearest point (to ``3e-13`` of its length).
    The plane through the box's nearest point orthogonal to the gap supports the box
    whatever ``t`` (it is the projection onto the box). Compiled, one row at a time
    (:func:`_box_plane`).
    """
    shadow = shadow_radius(epsilon, 3) * sigma if sigma > 0 else 0.0
    a, b, ok = np.zeros((len(index), 3)), np.zeros(len(index)), np.zeros(len(index), np.bool_)
    _box_planes(np.ascontiguousarray(start, dtype=np.float64), np.ascontiguousarray(end, dtype=np.float64),
                np.ascontiguousarray(centers, dtype=np.float64), np.ascontiguousarray(0.5 * np.asarray(sizes, dtype=np.float64)),
                np.ascontiguousarray(yaws, dtype=np.float64), float(shadow), np.asarray(index, np.intp), a, b, ok)
    return a, b, ok


@numba.njit(cache=True)
def _polygon_planes(start, end, whitening, vertices, shadow, index, a, b, ok):
    for r in range(len(index)):
        o = index[r]
        b[r], ok[r] = _polygon_plane(whitening[o], start[r], end[r], vertices[o], shadow[o], a[r])


@numba.njit(cache=True)
def _polygon_plane(w, start, end, vertices, shadow, a):
    """One row of :func:`segment_polygon_planes`: writes ``a``, returns ``(b, ok)``."""
    count = len(vertices)
    verts = np.empty((count, 2))
    for v in range(count):
        verts[v, 0] = w[0, 0] * vertices[v, 0] + w[0, 1] * vertices[v, 1]
        verts[v, 1] = w[1, 0] * vertices[v, 0] + w[1, 1] * vertices[v, 1]
    ends = np.empty((2, 2))
    ends[0, 0], ends[0, 1] = w[0, 0] * start[0] + w[0, 1] * start[1], w[1, 0] * start[0] + w[1, 1] * start[1]
    ends[1, 0], ends[1, 1] = w[0, 0] * end[0] + w[0, 1] * end[1], w[1, 0] * end[0] + w[1, 1] * end[1]
    on_segment, on_obstacle, candidate = np.empty(2), np.empty(2), np.empty(2)
    best = np.inf
    for e in range(2):  # an end against every edge
        for v in range(count):
            _nearest_on_segment(ends[e], verts[v], verts[(v + 1) % count], candidate)
            gap = (ends[e, 0] - candidate[0]) ** 2 + (ends[e, 1] - candidate[1]) ** 2
            if gap < best:
                best = gap
                on_segment[:] = ends[e]
                on_obstacle[:] = candidate
    for v in range(count):  # a vertex against the segment
        _nearest_on_segment(verts[v], ends[0], ends[1], candidate)
        gap = (verts[v, 0] - candidate[0]) ** 2 + (verts[v, 1] - candidate[1]) ** 2
        if gap < best:
            best = gap
            on_segment[:] = candidate
            on_obstacle[:] = verts[v]
    return _support_plane(w, on_segment, on_obstacle, verts, ends, shadow, a)


@numba.njit(cache=True)
def _box_planes(start, end, centers, half, yaws, shadow, index, a, b, ok):
    for r in range(len(index)):
        o = index[r]
        b[r], ok[r] = _box_plane(start[r], end[r], centers[o], half[o], yaws[o], shadow, a[r])


@numba.njit(cache=True)
def _box_plane(start, end, center, half, yaw, shadow, a):
    """One row of :func:`segment_box_planes`: writes ``a``, returns ``(b, ok)``."""
    rot = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])  # box frame → world
    local0, step = rot.T @ (start - center), rot.T @ (end - start)
    ratio = 0.5 * (np.sqrt(5.0) - 1.0)
    lo, hi = 0.0, 1.0
    x1, x2 = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    f1, f2 = _box_gap(local0 + x1 * step, half), _box_gap(local0 + x2 * step, half)
    for _ in range(_GOLDEN_STEPS):  # golden section: the minimum of the convex gap stays in [lo, hi]
        if f1 <= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - ratio * (hi - lo)
            f1 = _box_gap(local0 + x1 * step, half)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + ratio * (hi - lo)
            f2 = _box_gap(local0 + x2 * step, half)
    t = 0.5 * (lo + hi)
    near = local0 + t * step
    on_box = center + rot @ np.minimum(np.maximum(near, -half), half)
    corners = np.empty((8, 3))
    for c in range(8):
        corners[c] = center + rot @ (half * np.array([2.0 * (c & 1) - 1.0, 2.0 * ((c >> 1) & 1) - 1.0, 2.0 * ((c >> 2) & 1) - 1.0]))
    ends = np.empty((2, 3))
    ends[0], ends[1] = start, end
    return _support_plane(np.eye(3), start + t * (end - start), on_box, corners, ends, shadow, a)


@numba.njit(cache=True, inline="always")
def _box_gap(point, half):
    """Distance from a point (box frame) to the box ``[−h, h]³``."""
    gap = 0.0
    for k in range(3):
        gap += max(abs(point[k]) - half[k], 0.0) ** 2
    return np.sqrt(gap)


@numba.njit(cache=True)
def _nearest_on_segment(point, start, end, out):
    """Write the point of segment ``start → end`` nearest to ``point`` into ``out``."""
    len2, dot = 0.0, 0.0
    for k in range(len(point)):
        len2 += (end[k] - start[k]) ** 2
        dot += (point[k] - start[k]) * (end[k] - start[k])
    t = _clamp01(dot, len2)
    for k in range(len(point)):
        out[k] = start[k] + t * (end[k] - start[k])


@numba.njit(cache=True)
def _support_plane(w, on_segment, on_obstacle, obstacle_points, ends, shadow, a):
    """The robot-side row ``−(Wᵀn)·p ≤ −(n·c + r)`` (normalised) of the whitened plane
    through the obstacle's closest point ``c`` with normal ``n`` towards the segment,
    shifted by ``r`` to touch the shadow: writes ``a``, returns ``(b, ok)``, ``ok`` where it
    separates the (whitened) obstacle's points from the segment's ends."""
    d = len(on_segment)
    n = on_segment - on_obstacle
    gap = np.sqrt(np.sum(n * n))
    if not gap > _SEPARATED:
        return 0.0, False
    n /= gap
    support = np.sum(n * on_obstacle)
    slack = 1e-9 * (1.0 + np.max(np.abs(on_obstacle)))
    for v in range(len(obstacle_points)):
        if np.sum(n * obstacle_points[v]) > support + slack:
            return 0.0, False
    for e in range(len(ends)):
        if np.sum(n * ends[e]) < support + gap - slack - 1e-6 * gap:
            return 0.0, False
    norm = 0.0
    for k in range(d):
        a[k] = 0.0
        for m in range(d):
            a[k] -= w[m, k] * n[m]
        norm += a[k] * a[k]
    norm = np.sqrt(norm)
    for k in range(d):
        a[k] /= norm
    return -(support + shadow) / norm, True


# ---------------------------------------------------------------------------------------
# the cells
# ---------------------------------------------------------------------------------------
def with_braking_segments(cells: Cells, starts: np.ndarray, ends: np.ndarray, covs: np.ndarray, radius: np.ndarray, quantile: float,
                          obstacles: ObstacleSet | None = None, boxes=None) -> Cells:
    """``cells`` with the rows of the robots that have a braking segment rebuilt from the
    segments (module docstring).

    Parameters
    ----------
    cells : Cells
        The point cells of :func:`.cell.build_cells` (robot rows with ``source`` the
        neighbour, obstacle rows with ``source`` the obstacle or box).
    starts, ends : numpy.ndarray
        ``(N, d)`` the segments ``[p̂_i, stop_i]`` (``ends == starts`` for a point).
    covs, radius, quantile
        Σ_i ``(N, d, d)``, r_i ``(N,)`` and ``Φ⁻¹(√(1 − δ))``, as the cells were built with.
    obstacles : ObstacleSet, optional
        The 2-D obstacles as the cells saw them (shifted to their estimates).
    boxes : tuple, optional
        3-D boxes ``(centers, sizes, yaws, σ_o, ε)`` as the cells saw them (Σ_o = σ_o² I).
    """
    moving = np.any(ends != starts, axis=1)
    if not moving.any():
        return cells
    A, b = cells.A.copy(), cells.b.copy()
    _robot_rows(cells, A, b, moving, starts, ends, covs, radius, quantile)
    _obstacle_rows(cells, A, b, moving, starts, ends, covs, radius, quantile, obstacles, boxes)
    return replace(cells, A=A, b=b)


def _robot_rows(cells, A, b, moving, starts, ends, covs, radius, quantile):
    """Rebuild, in place, the pair rows with a segment on either side."""
    robot = cells.valid & (cells.kind == int(Kind.ROBOT))
    other = np.where(robot, cells.source, 0)
    owner, slot = np.nonzero(robot & (moving[:, None] | moving[other]))
    if len(owner) == 0:
        return
    args = (owner, slot, cells.source[owner, slot], np.ascontiguousarray(starts, dtype=np.float64),
            np.ascontiguousarray(ends, dtype=np.float64), covs, np.ascontiguousarray(radius, dtype=np.float64), float(quantile), A, b)
    if use_parallel(len(starts)):
        _pair_rows_parallel(*args)
    else:
        _pair_rows(0, len(owner), *args)


@numba.njit(cache=True, parallel=True)
def _pair_rows_parallel(owner, slot, other, starts, ends, covs, radius, quantile, A, b):
    chunk = 1024
    for c in numba.prange((len(owner) + chunk - 1) // chunk):
        _pair_rows(c * chunk, min(len(owner), (c + 1) * chunk), owner, slot, other, starts, ends, covs, radius, quantile, A, b)


@numba.njit(cache=True)
def _pair_rows(lo, hi, owner, slot, other, starts, ends, covs, radius, quantile, A, b):
    """Rows ``lo … hi − 1``: robot ``owner[k]``'s row ``slot[k]`` against ``other[k]``, from
    the pair's segments taken in index order (so the two rows are exactly ``(a, b)`` and
    ``(−a, −b)`` before the buffers); rows of meeting segments are left as they are."""
    d = starts.shape[1]
    cp, cq, a = np.empty(d), np.empty(d), np.empty(d)
    for k in range(lo, hi):
        i, j = owner[k], other[k]
        first, second = min(i, j), max(i, j)
        _closest_pair(starts[first], ends[first], starts[second], ends[second], cp, cq)
        if not _plane(cp, cq, 1.0 if i == first else -1.0, a) > _SEPARATED:
            continue
        quad = 0.0
        for m in range(d):
            for n in range(d):
                quad += a[m] * covs[i, m, n] * a[n]
            A[i, slot[k], m] = a[m]
        b[i, slot[k]] = _midplane_offset(a, cp, cq) - (0.5 * (radius[i] + radius[j]) + quantile * np.sqrt(max(quad, 0.0)))


def _obstacle_rows(cells, A, b, moving, starts, ends, covs, radius, quantile, obstacles, boxes):
    """Rebuild, in place, the obstacle rows of the robots with a segment."""
    i, m = np.nonzero(cells.valid & (cells.kind == int(Kind.OBSTACLE)) & moving[:, None])
    if len(i) == 0:
        return
    o = cells.source[i, m]
    if boxes is not None:
        a, off, ok = segment_box_planes(starts[i], ends[i], *boxes, index=o)
    elif obstacles is not None and obstacles.count:
        a, off, ok = segment_polygon_planes(starts[i], ends[i], obstacles, o)
    else:
        return
    row_b = off - buffer(a, covs[i], radius[i], quantile)
    A[i[ok], m[ok]], b[i[ok], m[ok]] = a[ok], row_b[ok]
