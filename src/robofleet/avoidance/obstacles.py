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
