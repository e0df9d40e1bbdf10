"""Separating planes between robots and static obstacles with uncertain position
(Zhu et al. 2022, appendix A: Lemma 1 and Theorem 1, the ε-shadow).

An obstacle is a convex polygon ``Ô_o`` displaced by ``d_o ~ N(0, Σ_o)``. By Lemma 1 the
displacement stays in ``D_o = {d : dᵀ Σ_o⁻¹ d ≤ F⁻¹_{χ²_d}(1 − ε)}`` with probability
``1 − ε``, so ``S_o = Ô_o ⊕ D_o`` is an ε-shadow (Theorem 1). After whitening with
``W = Σ_o^{-1/2}``, ``D_o`` is a ball of radius ``r = √F⁻¹(1 − ε)`` and ``S_o`` is the
polygon grown by that ball (exactly; we do not over-approximate by pushing faces).
The max-margin plane between the robot estimate ``q`` and the grown polygon has normal
``n = (q − c)/‖q − c‖`` (``c`` the closest point of the polygon to ``q``); shifted to touch
the shadow it is ``n·x = n·c + r``. Back in world coordinates the robot's side is
``aᵀp ≤ b`` with ``a = −Wᵀn``, ``b = −(h(n) + r)``, then normalised, where
``h(n) = max_v n·v`` is the polygon's support in direction ``n`` (``= n·c`` for the
max-margin normal).

Estimates on the boundary or inside. When ``q`` lies on the polygon (a vertex, an edge)
or inside it, ``q − c`` gives no direction; ``n`` is then the outward normal of the face
whose line ``q`` is farthest beyond (the least negative signed distance: an edge through
``q`` on the boundary, the nearest edge inside), and the robot's side is beyond that face
grown by ``r``: its cell lies outside the obstacle, so the filtered step heads out.
Any unit ``n`` gives a plane that keeps the whole shadow on the far side, because the
offset is the support ``h(n) + r`` of the grown polygon (``c ∈ Ô`` and the ``r``-ball);
the choice of ``n`` only decides how much room the robot gets.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from ..core import geometry


@dataclass(frozen=True)
class ObstacleSet:
    """Convex obstacles prepared for vectorized plane computation.

    Attributes
    ----------
    vertices: ``(O, V, d)`` counter-clockwise vertices, padded by repeating the last one.
    whitening: ``(O, d, d)`` the matrices ``W_o = Σ_o^{-1/2}`` (identity when ``Σ_o = 0``).
    shadow_radius: ``(O,)`` radius ``r`` of the ε-shadow in whitened space (0 when ``Σ_o = 0``).
    lo, hi: ``(O, d)`` axis-aligned bounds of the shadows (for local-box selection).
    """

    vertices: np.ndarray
    whitening: np.ndarray
    shadow_radius: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    @property
    def count(self) -> int:
        return len(self.vertices)

    def near(self, points: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """The pairs (point, obstacle) whose box of half-width ``reach`` around the point
        meets the obstacle's bounds: ``p + reach ≥ lo`` and ``p − reach ≤ hi`` on every
        axis, as ``(owner, index)`` in increasing point, then obstacle, order (the order of
        ``np.nonzero`` on the ``(N, O)`` test).

        The obstacles' bounds grown by ``reach`` and one cell more are bucketed on a grid of
        side ``h = max(2 reach, median obstacle extent)`` (each obstacle under the few
        cells it covers, the buckets sorted by cell key); a point tests exactly the
        obstacles of its own cell, in increasing index. The grid is conservative — a point
        that meets an obstacle lies within ``reach`` (plus rounding, far less than a cell)
        of its bounds, so inside the grown cells — and the test is the same floating-point
        comparison, so the result equals the ``(N, O)`` test's. Cost ``O(N log C + O·c +
        pairs tested)`` for ``C`` bucket entries and ``c`` cells per obstacle; when the
        buckets would outnumber ``16 (N + O)`` (obstacles far larger than the points'
        spacing) every pair is tested, compiled.
        """
        p = np.ascontiguousarray(points, dtype=np.float64)
        n, count = len(p), self.count
        if n == 0 or count == 0:
            return np.zeros(0, np.intp), np.zeros(0, np.intp)
        finite = np.isfinite(p).all(axis=1)
        if not finite.all():  # a NaN or infinite coordinate meets no obstacle (the test is false)
            kept = np.flatnonzero(finite)
            owner, index = self.near(p[kept], reach)
            return kept[owner], index
        lo, hi = np.ascontiguousarray(self.lo, dtype=np.float64), np.ascontiguousarray(self.hi, dtype=np.float64)
        reach = float(reach)
        if not 0.0 <= reach < np.inf:  # NaN, negative or infinite: no grid, the test itself
            return _pairs_all(p, lo, hi, reach)
        h = max(2.0 * reach, float(np.median(np.max(hi - lo, axis=1))), 1e-9)
        buckets = _obstacle_buckets(p, lo, hi, reach, h, 16 * (n + count) + 4096)
        if buckets is None:
            return _pairs_all(p, lo, hi, reach)
        return _pairs_in_buckets(p, lo, hi, reach, h, *buckets)

    @classmethod
    def build(cls, polygons: Sequence[np.ndarray], covariances: np.ndarray, epsilon: float) -> "ObstacleSet":
        """Prepare obstacles ``polygons`` (list of ``(V_k, 2)``) with position covariances ``(O, 2, 2)``."""
        if len(polygons) == 0:
            z = np.zeros((0, 2))
            return cls(np.zeros((0, 1, 2)), np.zeros((0, 2, 2)), np.zeros(0), z, z)
        v_max = max(len(p) for p in polygons)
        verts = np.stack([np.vstack([p, np.repeat(p[-1:], v_max - len(p), 0)]) for p in map(geometry.ensure_ccw, polygons)])
        covs = np.asarray(covariances, dtype=float)
        d = verts.shape[-1]
        from scipy.stats import chi2  # loaded on first use: validating a scenario needs no scipy.stats

        radius_quantile = float(np.sqrt(chi2.ppf(1.0 - epsilon, df=d))) if epsilon > 0 else np.inf
        whitening, radii, extents = [], [], []
        for cov in covs:
            if np.allclose(cov, 0.0):
                whitening.append(np.eye(d)), radii.append(0.0), extents.append(np.zeros(d))
                continue
            w, v = np.linalg.eigh(cov)
            w = np.maximum(w, 1e-12 * w.max())
            whitening.append((v / np.sqrt(w)) @ v.T)
            radii.append(radius_quantile)
            extents.append(radius_quantile * np.sqrt(np.diag(cov)))
        ext = np.asarray(extents)
        return cls(verts, np.asarray(whitening), np.asarray(radii), verts.min(axis=1) - ext, verts.max(axis=1) + ext)


def obstacle_planes(points: np.ndarray, obstacles: ObstacleSet, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Robot-side half-planes ``aᵀp ≤ b`` (unit ``a``) between points and their shadows.

    Parameters
    ----------
    points
        ``(R, 2)`` robot position estimates, one row per (robot, obstacle) pair.
    index
        ``(R,)`` obstacle index of each row.

    Returns
    -------
    ``a (R, 2)`` and ``b (R,)`` before the robot's own chance buffer.
    """
    w = obstacles.whitening[index]
    q = np.einsum("rij,rj->ri", w, points)
    verts = np.einsum("rij,rvj->rvi", w, obstacles.vertices[index])
    start, end = verts, np.roll(verts, -1, axis=1)
    gap = q - _closest_on_boundary(q, start, end)
    dist = np.hypot(gap[:, 0], gap[:, 1])
    apart = ~_inside_convex(q, start, end) & (dist > SEPARATION_TOL * (1.0 + np.abs(q).max(axis=1)))
    n = np.where(apart[:, None], gap / np.where(apart, dist, 1.0)[:, None], _face_normal(q, start, end))
    support = np.einsum("rvd,rd->rv", verts, n).max(axis=1)
    a = -np.einsum("rji,rj->ri", w, n)  # -Wᵀ n
    b = -(support + obstacles.shadow_radius[index])
    norm = np.hypot(a[:, 0], a[:, 1])
    return a / norm[:, None], b / norm


SEPARATION_TOL = 1e-12
"""Relative distance below which an estimate counts as on the obstacle's boundary (its
direction from the closest point is then rounding noise)."""


def _face_normal(q, start, end):
    """Outward unit normal ``(R, 2)`` of the face of each counter-clockwise polygon whose
    line ``q`` lies farthest beyond (zero-length padding edges excluded)."""
    edge = end - start
    length = np.hypot(edge[..., 0], edge[..., 1])
    normal = np.stack([edge[..., 1], -edge[..., 0]], axis=-1) / np.where(length > 0, length, 1.0)[..., None]
    beyond = np.where(length > 0, np.einsum("rvd,rvd->rv", normal, q[:, None] - start), -np.inf)
    return normal[np.arange(len(q)), np.argmax(beyond, axis=1)]


def _closest_on_boundary(q, start, end):
    """Closest point of each polygon boundary (edges ``start→end``, ``(R, V, 2)``) to ``q (R, 2)``."""
    seg = end - start
    len2 = np.einsum("rvd,rvd->rv", seg, seg)
    t = np.einsum("rvd,rvd->rv", q[:, None] - start, seg) / np.where(len2 > 0, len2, 1.0)
    pts = start + np.clip(t, 0.0, 1.0)[..., None] * seg
    k = np.argmin(np.linalg.norm(pts - q[:, None], axis=-1), axis=1)
    return pts[np.arange(len(q)), k]


def _inside_convex(q, start, end):
    edge = end - start
    rel = q[:, None] - start
    cross = edge[..., 0] * rel[..., 1] - edge[..., 1] * rel[..., 0]
    nondegenerate = np.einsum("rvd,rvd->rv", edge, edge) > 0
    return np.all((cross > 0) | ~nondegenerate, axis=1)


def wall_planes(bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Half-planes ``aᵀp ≤ b`` (unit outward ``a``) of a convex counter-clockwise boundary."""
    start, end = geometry.polygon_edges(geometry.ensure_ccw(bounds))
    edge = end - start
    a = np.stack([edge[:, 1], -edge[:, 0]], axis=-1)
    a /= np.hypot(a[:, 0], a[:, 1])[:, None]
    return a, np.einsum("kd,kd->k", a, start)


def _obstacle_buckets(p, lo, hi, reach, h, budget):
    """The grid of :meth:`ObstacleSet.near`: the points' cell range ``(origin, span)`` and the
    bucket entries ``(keys, obstacle)`` sorted by key (obstacles in increasing index within
    a key); ``None`` when the entries would exceed ``budget`` or the keys overflow."""
    cells = np.floor(p / h)
    origin, top = cells.min(axis=0), cells.max(axis=0)
    span = top - origin + 1
    if float(np.prod(span)) > 2.0 ** 62:
        return None
    first = np.maximum(np.floor((lo - reach) / h) - 1, origin)
    last = np.minimum(np.floor((hi + reach) / h) + 1, top)
    covered = np.where(np.all(last >= first, axis=1), np.prod(np.maximum(last - first + 1, 0), axis=1), 0)
    if float(covered.sum()) > budget:
        return None
    keys, owner = _fill_buckets(first.astype(np.int64), last.astype(np.int64), origin.astype(np.int64),
                                span.astype(np.int64), covered.astype(np.int64))
    order = np.argsort(keys, kind="stable")
    return origin.astype(np.int64), span.astype(np.int64), keys[order], owner[order]


@numba.njit(cache=True)
def _fill_buckets(first, last, origin, span, covered):
    """One entry ``(cell key, obstacle)`` per cell each obstacle's grown bounds cover."""
    total = 0
    for o in range(len(covered)):
        total += covered[o]
    keys, owner = np.empty(total, np.int64), np.empty(total, np.intp)
    d, k = first.shape[1], 0
    cell = np.empty(d, np.int64)
    for o in range(len(covered)):
        if covered[o] == 0:
            continue
        for a in range(d):
            cell[a] = first[o, a]
        for _ in range(covered[o]):
            key = 0
            for a in range(d):
                key = key * span[a] + (cell[a] - origin[a])
            keys[k], owner[k] = key, o
            k += 1
            for a in range(d - 1, -1, -1):  # next cell, last axis fastest
                cell[a] += 1
                if cell[a] <= last[o, a]:
                    break
                cell[a] = first[o, a]
    return keys, owner


@numba.njit(cache=True, inline="always")
def _meets(p, i, lo, hi, o, reach):
    """The local-box test of :meth:`ObstacleSet.near`, exactly as the ``(N, O)`` expression."""
    for a in range(p.shape[1]):
        if not (p[i, a] + reach >= lo[o, a] and p[i, a] - reach <= hi[o, a]):
            return False
    return True


@numba.njit(cache=True)
def _pairs_in_buckets(p, lo, hi, reach, h, origin, span, keys, owner):
    """Each point's obstacles from its own cell's bucket: a counting pass, then a writing one."""
    n, d = p.shape
    begin, end = np.empty(n, np.int64), np.empty(n, np.int64)
    count = np.zeros(n + 1, np.int64)
    for i in range(n):
        key = 0
        for a in range(d):
            key = key * span[a] + (np.int64(np.floor(p[i, a] / h)) - origin[a])
        begin[i] = np.searchsorted(keys, key, "left")
        end[i] = np.searchsorted(keys, key, "right")
        for k in range(begin[i], end[i]):
            count[i + 1] += _meets(p, i, lo, hi, owner[k], reach)
    for i in range(n):
        count[i + 1] += count[i]
    point, obstacle = np.empty(count[n], np.intp), np.empty(count[n], np.intp)
    for i in range(n):
        w = count[i]
        for k in range(begin[i], end[i]):
            if _meets(p, i, lo, hi, owner[k], reach):
                point[w], obstacle[w] = i, owner[k]
                w += 1
    return point, obstacle


@numba.njit(cache=True)
def _pairs_all(p, lo, hi, reach):
    """Every (point, obstacle) pair tested: a counting pass, then a writing one."""
    n, count = len(p), 0
    for i in range(n):
        for o in range(len(lo)):
            count += _meets(p, i, lo, hi, o, reach)
    point, obstacle = np.empty(count, np.intp), np.empty(count, np.intp)
    w = 0
    for i in range(n):
        for o in range(len(lo)):
            if _meets(p, i, lo, hi, o, reach):
                point[w], obstacle[w] = i, o
                w += 1
    return point, obstacle
