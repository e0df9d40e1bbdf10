"""Vectorized geometry kernels shared by every family.

All functions take float64 arrays with points on the last axis and never loop over
robots in Python.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def box_vertices(center: Sequence[float] | np.ndarray, size: Sequence[float] | np.ndarray, yaw: float = 0.0) -> np.ndarray:
    """Counter-clockwise vertices ``(4, 2)`` of a ``size[0] × size[1]`` box at ``center``."""
    cx, cy = np.asarray(center, dtype=float)[:2]
    hx, hy = 0.5 * np.asarray(size, dtype=float)[:2]
    corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = np.cos(yaw), np.sin(yaw)
    return corners @ np.array([[c, s], [-s, c]]) + [cx, cy]


def polygon_edges(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Edge start and end points ``(V, 2)`` of a closed polygon given by its vertices."""
    v = np.asarray(vertices, dtype=float)
    return v, np.roll(v, -1, axis=0)


def point_segment_distance(points: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Distance from each point to each segment.

    ``points`` has shape ``(..., d)``; ``start``/``end`` ``(S, d)``. Returns ``(..., S)``.
    """
    p = np.asarray(points, dtype=float)[..., None, :]
    seg = end - start
    length2 = np.einsum("sd,sd->s", seg, seg)
    t = np.einsum("...sd,sd->...s", p - start, seg) / np.where(length2 > 0, length2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    closest = start + t[..., None] * seg
    return np.linalg.norm(p - closest, axis=-1)


def points_in_convex_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Boolean mask of points strictly inside a convex counter-clockwise polygon."""
    start, end = polygon_edges(vertices)
    edge = end - start
    rel = np.asarray(points, dtype=float)[..., None, :] - start
    cross = edge[:, 0] * rel[..., 1] - edge[:, 1] * rel[..., 0]
    return np.all(cross > 0, axis=-1)


def points_in_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Boolean mask of points strictly inside a simple polygon (even-odd rule), any winding."""
    p = np.asarray(points, dtype=float)
    x, y = p[..., 0, None], p[..., 1, None]
    start, end = polygon_edges(vertices)
    y0, y1 = start[:, 1], end[:, 1]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = start[:, 0] + (y - y0) * (end[:, 0] - start[:, 0]) / (y1 - y0)
    return (np.count_nonzero(crosses & (x < x_at), axis=-1) % 2) == 1


def polygon_distance(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Distance from points ``(..., 2)`` to a polygon; 0 inside, boundary distance outside."""
    start, end = polygon_edges(vertices)
    d = point_segment_distance(points, start, end).min(axis=-1)
    return np.where(points_in_polygon(points, vertices), 0.0, d)


def ensure_ccw(vertices: np.ndarray) -> np.ndarray:
    """The same polygon with counter-clockwise vertex order (shoelace sign)."""
    v = np.asarray(vertices, dtype=float)
    x, y = v[:, 0], v[:, 1]
    area2 = np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)
    return v if area2 > 0 else v[::-1].copy()


def close_pairs(points: np.ndarray, radius: float) -> np.ndarray:
    """All index pairs ``(i, j)``, ``i < j``, with ``‖p_i − p_j‖ < radius`` (k-d tree, O(N log N + K))."""
    from scipy.spatial import cKDTree  # imported on use: scenario files are read without scipy

    pts = np.asarray(points, dtype=float)
    if len(pts) < 2:
        return np.empty((0, 2), dtype=np.intp)
    pairs = cKDTree(pts).query_pairs(radius, output_type="ndarray")
    if len(pairs) == 0:
        return pairs.reshape(0, 2)
    d = np.linalg.norm(pts[pairs[:, 0]] - pts[pairs[:, 1]], axis=1)
    return pairs[d < radius]


def nearest_neighbour_distance(points: np.ndarray) -> np.ndarray:
    """Distance from each point to its nearest other point (``inf`` for a single point)."""
    from scipy.spatial import cKDTree  # imported on use: scenario files are read without scipy

    pts = np.asarray(points, dtype=float)
    if len(pts) < 2:
        return np.full(len(pts), np.inf)
    d, _ = cKDTree(pts).query(pts, k=2)
    return d[:, 1]


def rotation_2d(angle: float | np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 2, 2)`` for angles ``(...)`` (counter-clockwise positive)."""
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
