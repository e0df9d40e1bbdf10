"""Geometry of avoidance runs as drawn, without drawing: the drawn area of a run, box
footprints, cells as polygons (Eq. 13: the intersection of a robot's half-planes, clipped
to the drawn area or to the robot's local box) and uncertainty ellipses.

Shared by the matplotlib figures and animations (:mod:`robofleet.viz.avoidance`), the
replay page (:mod:`robofleet.viz.replay.avoidance`) and the environment's renderer; it
imports numpy only, so building a replay page loads no plotting library.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..core.trace import Trace

TRAIL_STEPS = 60
"""Steps of trail drawn behind each robot in an animation."""


def is_three_d(trace: Trace) -> bool:
    """Whether the run took place in 3-D (positions with three coordinates)."""
    return trace.positions.shape[2] == 3


def view_extent(trace: Trace) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corner of the drawn (x, y) area: the 2-D workspace, else the
    footprint of the 3-D workspace box, else the positions with a 1 m margin."""
    if trace.workspace is not None and not is_three_d(trace):
        x0, y0, x1, y1 = trace.workspace.extent
        return np.array([x0, y0]), np.array([x1, y1])
    box = trace.metadata.get("bounds3d")
    if box:
        return np.array([box[0], box[1]], float), np.array([box[3], box[4]], float)
    xy = trace.positions[..., :2]
    return xy.min(axis=(0, 1)) - 1.0, xy.max(axis=(0, 1)) + 1.0


def height_range(trace: Trace) -> tuple[float, float]:
    """Floor and ceiling of a 3-D run (the workspace box, else the flown heights)."""
    box = trace.metadata.get("bounds3d")
    if box:
        return float(box[2]), float(box[5])
    z = trace.positions[..., 2]
    return float(z.min()), float(max(z.max(), z.min() + 1e-9))


def box_footprint(center: Sequence[float], size: Sequence[float], yaw: float) -> np.ndarray:
    """Corners ``(4, 2)`` of a box's footprint: its (x, y) rectangle rotated by ``yaw``."""
    half = 0.5 * np.asarray(size, float)[:2]
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half
    c, s = np.cos(yaw), np.sin(yaw)
    return corners @ np.array([[c, -s], [s, c]]).T + np.asarray(center, float)[:2]



def clip_halfplane(polygon: np.ndarray, a: np.ndarray, b: float) -> np.ndarray:
    """Sutherland–Hodgman clip of a convex polygon ``(k, 2)`` by ``{p : a·p ≤ b}``."""
    out = []
    for p, q in zip(polygon, np.roll(polygon, -1, axis=0)):
        fp, fq = a @ p - b, a @ q - b
        if fp <= 0:
            out.append(p)
        if fp * fq < 0:
            out.append(p + (q - p) * fp / (fp - fq))
    return np.array(out).reshape(-1, 2)


def local_box_view(trace: Trace) -> float | None:
    """Half-width R_loc of the local box a robot's cell is drawn in, if the run recorded a
    finite one: a robot builds its cell from the neighbours and obstacles inside
    p̂_i ± R_loc (docs/theory/buavc.md "Cell"), so beyond that box its cell says nothing
    it knows, and drawn to the workspace's edge every free robot's cell would cover the
    whole workspace under the others'."""
    value = trace.metadata.get("local_box")
    try:
        half = float(value)
    except (TypeError, ValueError):
        return None
    return half if np.isfinite(half) and half > 0 else None


def box_clip(polygon: np.ndarray, centre: np.ndarray, half: float) -> np.ndarray:
    """The convex ``polygon`` cut to the square ``centre ± half``."""
    for axis in range(2):
        for sign in (1.0, -1.0):
            a = np.zeros(2)
            a[axis] = sign
            polygon = clip_halfplane(polygon, a, sign * centre[axis] + half)
            if len(polygon) < 3:
                return polygon
    return polygon


def cell_polygon(A: np.ndarray, b: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Vertices of the cell ``{p : A p ≤ b}`` (Eq. 13: the intersection of the robot's
    half-planes) inside the convex polygon ``clip``; rows with ``a = 0`` are padding."""
    polygon = np.asarray(clip, float)
    for a, offset in zip(A, b):
        if np.any(a):
            polygon = clip_halfplane(polygon, a, offset)
        if len(polygon) < 3:
            break
    return polygon


def clip_region(trace: Trace) -> np.ndarray:
    """The convex polygon cells are drawn in: the 2-D workspace bounds, else the view box."""
    if trace.workspace is not None and not is_three_d(trace):
        return np.asarray(trace.workspace.bounds, float)
    lo, hi = view_extent(trace)
    return np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]], float)


def uncertainty_ellipse(cov: np.ndarray, k: float) -> tuple[float, float, float]:
    """Width, height and angle (degrees) of the k-σ ellipse of a 2×2 covariance."""
    values, vectors = np.linalg.eigh(np.asarray(cov, float))
    values = np.maximum(values, 0.0)
    angle = float(np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1])))
    return 2 * k * float(np.sqrt(values[1])), 2 * k * float(np.sqrt(values[0])), angle



# -- cells in bulk ------------------------------------------------------------------------
def halfplanes_of_polygon(polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` with ``{p : A p ≤ b}`` the convex polygon (either orientation)."""
    polygon = np.asarray(polygon, float)
    x, y = polygon[:, 0], polygon[:, 1]
    if np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)) < 0:
        polygon = polygon[::-1]
    edges = np.roll(polygon, -1, axis=0) - polygon
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
    return normals, np.einsum("kd,kd->k", normals, polygon)


def cell_polygons(A: np.ndarray, b: np.ndarray, clip: np.ndarray, chunk: int = 20_000) -> tuple[np.ndarray, np.ndarray]:
    """Many cells at once: vertex counts ``(B,)`` and the stacked counter-clockwise
    vertices ``(sum, 2)`` of each ``{p : A[k] p ≤ b[k]} ∩ clip`` (``A (B, m, 2)``,
    ``b (B, m)``; rows with ``a = 0`` are padding; a cell of fewer than three vertices has
    count 0). The same polygons as :func:`cell_polygon`, found as the feasible pairwise
    intersections of the boundary lines."""
    A, b = np.asarray(A, float).reshape(-1, *np.shape(A)[-2:]), np.asarray(b, float).reshape(-1, np.shape(b)[-1])
    clip_A, clip_b = halfplanes_of_polygon(clip)
    counts, vertices = [], []
    for start in range(0, len(A), chunk):
        n, v = _cell_chunk(A[start:start + chunk], b[start:start + chunk], clip_A, clip_b)
        counts.append(n)
        vertices.append(v)
    return (np.concatenate(counts) if counts else np.zeros(0, np.int64)), (np.concatenate(vertices) if vertices else np.zeros((0, 2)))


def _cell_chunk(A: np.ndarray, b: np.ndarray, clip_A: np.ndarray, clip_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    B = len(A)
    active = np.any(A != 0, axis=-1)
    AA = np.concatenate([A, np.broadcast_to(clip_A, (B, *clip_A.shape))], axis=1)
    bb = np.concatenate([np.where(active, b, np.inf), np.broadcast_to(clip_b, (B, len(clip_b)))], axis=1)
    i, j = np.triu_indices(AA.shape[1], 1)
    a1, a2, b1, b2 = AA[:, i], AA[:, j], bb[:, i], bb[:, j]
    det = a1[..., 0] * a2[..., 1] - a1[..., 1] * a2[..., 0]
    ok = (np.abs(det) > 1e-12) & np.isfinite(b1) & np.isfinite(b2)
    safe = np.where(ok, det, 1.0)
    with np.errstate(invalid="ignore"):
        pts = np.stack([(b1 * a2[..., 1] - b2 * a1[..., 1]) / safe, (a1[..., 0] * b2 - a2[..., 0] * b1) / safe], axis=-1)
        slack = np.einsum("bcd,bpd->bpc", AA, np.where(ok[..., None], pts, 0.0)) - bb[:, None, :]
    scale = 1e-9 * (1.0 + np.abs(np.where(np.isfinite(bb), bb, 0.0)))[:, None, :]
    ok &= np.all(slack <= scale, axis=-1)
    pts = np.where(ok[..., None], pts, 0.0)
    centre = pts.sum(axis=1) / np.maximum(ok.sum(axis=1), 1)[:, None]
    angle = np.where(ok, np.arctan2(pts[..., 1] - centre[:, None, 1], pts[..., 0] - centre[:, None, 0]), np.inf)
    order = np.argsort(angle, axis=1)
    pts, ok = np.take_along_axis(pts, order[..., None], axis=1), np.take_along_axis(ok, order, axis=1)
    repeat = np.zeros_like(ok)
    repeat[:, 1:] = ok[:, :-1] & (np.linalg.norm(pts[:, 1:] - pts[:, :-1], axis=-1) < 1e-9)
    ok &= ~repeat
    counts = ok.sum(axis=1)
    ok &= (counts >= 3)[:, None]
    return np.where(counts >= 3, counts, 0), pts[ok]
