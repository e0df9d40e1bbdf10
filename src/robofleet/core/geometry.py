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
    return (np.count_nonzero(edge_crossings(points, *polygon_edges(vertices)), axis=-1) % 2) == 1


def edge_crossings(points: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """``(..., E)``: whether the ray from each point ``(..., 2)`` towards +x crosses each
    edge ``start → end`` ``(E, 2)`` (the even-odd rule's count, half-open in y)."""
    p = np.asarray(points, dtype=float)
    x, y = p[..., 0, None], p[..., 1, None]
    y0, y1 = start[:, 1], end[:, 1]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = start[:, 0] + (y - y0) * (end[:, 0] - start[:, 0]) / (y1 - y0)
    return crosses & (x < x_at)


def polygon_distance(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Distance from points ``(..., 2)`` to a polygon; 0 inside, boundary distance outside."""
    start, end = polygon_edges(vertices)
    d = point_segment_distance(points, start, end).min(axis=-1)
    return np.where(points_in_polygon(points, vertices), 0.0, d)


class PolygonEdges:
    """The edges of several polygons stacked: ``start``, ``end`` ``(E, 2)`` with polygon
    ``k``'s edges at ``offsets[k]:offsets[k + 1]``, for :meth:`distance` to a run of them."""

    def __init__(self, polygons: tuple[np.ndarray, ...]):
        pairs = [polygon_edges(vertices) for vertices in polygons]
        self.start = np.concatenate([start for start, _ in pairs]) if pairs else np.empty((0, 2))
        self.end = np.concatenate([end for _, end in pairs]) if pairs else np.empty((0, 2))
        self.offsets = np.concatenate([[0], np.cumsum([len(start) for start, _ in pairs])]).astype(np.intp)

    def distance(self, points: np.ndarray, lo: int, hi: int) -> np.ndarray:
        """Distance from points ``(..., 2)`` to the nearest of polygons ``lo`` to ``hi − 1``
        (0 inside one): per polygon what :func:`polygon_distance` gives, from the same
        segment distances and :func:`edge_crossings`."""
        first, last = self.offsets[lo], self.offsets[hi]
        start, end = self.start[first:last], self.end[first:last]
        groups = self.offsets[lo:hi] - first
        boundary = np.minimum.reduceat(point_segment_distance(points, start, end), groups, axis=-1)
        crossings = np.add.reduceat(edge_crossings(points, start, end), groups, axis=-1)
        return np.where(crossings % 2 == 1, 0.0, boundary).min(axis=-1)


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


def close_pairs_in_cells(points: np.ndarray, radius: float) -> np.ndarray:
    """The pairs of :func:`close_pairs` (``i < j``, ``‖p_i − p_j‖ < radius``, the distance
    computed as there), sorted by ``i`` then ``j``, with numpy alone: reading a scenario
    checks its starts and goals with it and loads no scipy. :func:`close_pairs` keeps the
    k-d tree, faster per step for thousands of robots.

    A cell list: finite points ``(N, d)`` are binned into cubes of side ``(1 + 10⁻⁶) ·
    radius`` (or wider: at most 2²⁰ cubes along an axis). A pair closer than ``radius``
    differs by less than ``1 − 10⁻⁶`` sides along every axis, and binning a coordinate
    rounds it by less than 2⁻³⁰ sides (two roundings of a number below 2²⁰), so its cubes
    are equal or adjacent. Only cubes in the same or an adjacent position are paired, each
    adjacent pair once (the offsets whose first non-zero entry is positive), and the
    candidates are kept by the exact distance test. O(N log N + C) for C candidates, which
    points at least ``radius`` apart keep below a few per point.
    """
    pts = np.asarray(points, dtype=float)
    if len(pts) < 2 or not radius > 0:
        return np.empty((0, 2), dtype=np.intp)
    lower = pts.min(axis=0)
    side = max((1 + 1e-6) * radius, float((pts.max(axis=0) - lower).max()) / MAX_CELLS_PER_AXIS)
    cells = CellIndex(np.floor((pts - lower) / side).astype(np.int64))
    found_i, found_j = [], []
    for offset in half_neighbourhood(pts.shape[1]):
        i, j = cells.point_pairs(offset)
        found_i.append(i)
        found_j.append(j)
    i, j = np.concatenate(found_i), np.concatenate(found_j)
    gap = pts[i] - pts[j]
    close = np.sqrt(np.add.reduce(gap * gap, axis=1)) < radius
    i, j = i[close], j[close]
    first, second = np.minimum(i, j).astype(np.intp), np.maximum(i, j).astype(np.intp)
    order = np.argsort(first * len(pts) + second)
    return np.column_stack([first[order], second[order]])


MAX_CELLS_PER_AXIS = 2.0**20
"""Most cubes along one axis of :func:`close_pairs_in_cells` (cube indices stay exact integers)."""


def half_neighbourhood(dim: int) -> np.ndarray:
    """The zero offset, then the offsets in ``{−1, 0, 1}^dim`` whose first non-zero entry is
    positive: every adjacent cube pair is reached from exactly one of its two cubes."""
    grid = np.stack(np.meshgrid(*([np.array([-1, 0, 1])] * dim), indexing="ij"), -1).reshape(-1, dim)
    leading = np.array([row[np.flatnonzero(row)[0]] if row.any() else 0 for row in grid])
    return np.concatenate([np.zeros((1, dim), np.int64), grid[leading > 0]])


class CellIndex:
    """Points binned by integer cube coordinates ``(N, d)``: the occupied cubes, each as one
    integer key (the rank of each coordinate among the occupied ones, mixed radix)."""

    def __init__(self, cubes: np.ndarray):
        self.axis_values = [np.unique(cubes[:, k]) for k in range(cubes.shape[1])]
        keys = self.keys(cubes)
        self.order = np.argsort(keys, kind="stable")
        self.occupied, self.first, self.count = np.unique(keys[self.order], return_index=True, return_counts=True)
        self.occupied_cubes = cubes[self.order[self.first]]

    def keys(self, cubes: np.ndarray) -> np.ndarray:
        """The key of each cube ``(M, d)``, ``−1`` for a cube no point lies in along some axis."""
        key = np.zeros(len(cubes), np.int64)
        known = np.ones(len(cubes), bool)
        for k, values in enumerate(self.axis_values):
            rank = np.searchsorted(values, cubes[:, k])
            known &= values[np.minimum(rank, len(values) - 1)] == cubes[:, k]
            key = key * (len(values) + 1) + rank
        return np.where(known, key, -1)

    def point_pairs(self, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every pair of points ``(i, j)`` with ``j`` in the cube ``offset`` away from ``i``'s
        (for the zero offset, each pair of one cube once)."""
        other = self.keys(self.occupied_cubes + offset)
        at = np.minimum(np.searchsorted(self.occupied, other), len(self.occupied) - 1)
        a = np.flatnonzero((other >= 0) & (self.occupied[at] == other))
        b = at[a]
        i, owner = index_ranges(self.first[a], self.count[a])
        j, row = index_ranges(self.first[b][owner], self.count[b][owner])
        i = i[row]
        if not offset.any():
            i, j = i[i < j], j[i < j]
        return self.order[i], self.order[j]


def index_ranges(starts: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``arange(s, s + c)`` for every ``(s, c)``, concatenated, and the range each element is from."""
    owner = np.repeat(np.arange(len(counts)), counts)
    within = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
    return starts[owner] + within, owner


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
