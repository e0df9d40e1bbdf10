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
``aᵀp ≤ b`` with ``a = −Wᵀn``, ``b = −(n·c + r)``, then normalised.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

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
    closest = _closest_on_boundary(q, start, end)
    offset = q - closest
    dist = np.linalg.norm(offset, axis=-1)
    inside = _inside_convex(q, start, end)
    n = np.where(inside[:, None], -offset, offset) / np.maximum(dist, 1e-300)[:, None]
    a = -np.einsum("rji,rj->ri", w, n)  # -Wᵀ n
    b = -(np.einsum("ri,ri->r", n, closest) + obstacles.shadow_radius[index])
    norm = np.linalg.norm(a, axis=-1)
    return a / norm[:, None], b / norm


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
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    return a, np.einsum("kd,kd->k", a, start)
