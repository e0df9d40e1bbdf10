"""Static polygon obstacles in ORCA (van den Berg et al. 2011, Sec. 5, static obstacles; the
construction of the authors' library RVO2), compiled per robot for :mod:`.orca`.

**Obstacles.** Every obstacle is a closed polygon. Edge ``e`` runs from vertex ``e`` to
vertex ``next[e]`` with unit direction ``u_e``, and free space lies on its right: a solid
obstacle is listed counter-clockwise, a polygon that encloses the robots (the workspace's
walls) clockwise. Vertex ``e`` is *convex* when the turn ``prev → e → next`` is not to the
right (a corner free space wraps around); the corners of the walls, seen from inside, are
not.

**Velocity obstacle of an edge.** For robot A (radius ``r``, current velocity ``v``) and an
edge with endpoints ``a, b`` relative to A, the velocities that reach the edge grown by
``r`` within the obstacle horizon ``τ_o`` form ``VO = {w : ∃ t ∈ (0, τ_o], t w ∈ [a, b] ⊕
D(0, r)}``: a cone from the origin bounded by two *legs* (the tangents to ``D(a, r)``,
turned left, and to ``D(b, r)``, turned right), truncated by the *cut-off* (the segment
``[a, b]/τ_o`` pushed out by ``r/τ_o``, with the arcs of ``D(a/τ_o, r/τ_o)`` and
``D(b/τ_o, r/τ_o)`` at its ends). The obstacle does not move or take a share of the
avoidance, so A keeps the whole half-plane tangent to ``∂VO`` at the point nearest ``v``
(the paper's ``ORCA_{A|O}``, with no factor ½):

* A already overlaps the edge (distance ``≤ r``): the line through the origin whose normal
  points away from the nearest point (the nearest vertex, or the edge's outward normal);
  a non-convex vertex, or the far vertex when the next edge will also see it, adds none.
* Seen obliquely (A within ``r`` of the edge's line but beyond an end): both legs come from
  the near vertex, skipped when it is not convex.
* A leg at a non-convex vertex continues the edge itself (``∓u_e``). A leg at a convex
  vertex that would point into the neighbouring edge is replaced by that edge's direction
  and marked *foreign*: the neighbouring edge's own line covers that side, so a
  projection onto a foreign leg adds no line.
* Otherwise ``v`` is projected on the nearest of the cut-off arcs, the cut-off segment and
  the legs, and the line passes through that point of ``∂VO`` with the outward normal.

Every robot visits its edges nearest first (segment distance, ties by edge index) and
skips an edge whose two cut-off discs ``D(a/τ_o, r/τ_o)``, ``D(b/τ_o, r/τ_o)`` already lie
on the forbidden side of an earlier obstacle line (as RVO2 does; tolerance
:data:`COVERED_TOL`). Only edges within ``R = τ_o v_max + r`` with A strictly on their free
side are visited: edges that face away are covered by the ones that face A, and farther
edges cannot be reached within ``τ_o``.

**Why a robot stays out.** Let A start the step at least ``r`` from every obstacle, with
exact positions and ``Δt ≤ τ_o``, and let its new velocity ``v'`` satisfy every obstacle
line. (i) A truncated velocity obstacle ``K`` is convex (``[a, b] ⊕ D(0, r)`` is, and so
is the union of its scalings by ``s ≥ 1/τ_o``) and closed under scaling by ``λ ≥ 1``, so
every line supporting it at a point ``q`` has ``n·q ≤ 0``: the origin is on the allowed
side. (ii) Hence the covered test is sound: an earlier line with the origin on its allowed
side that leaves both cut-off discs (and so their convex hull, ``K``'s cut-off) on the
forbidden side leaves all of ``K``, which lies farther out from the origin (up to
:data:`COVERED_TOL` · Δt of depth). (iii) A motion that first meets the grown obstacles
within ``Δt`` meets them within ``v_max Δt + r ≤ R`` at a grown edge or a vertex arc whose
normal faces A, so A is strictly on the free side of that edge (or of one edge of that
vertex): a visited edge. (iv) Each visited edge's line supports its ``K`` (a leg at a
non-convex vertex, or a foreign leg, belongs to the neighbouring edge's velocity obstacle,
whose own line is the constraint there). So ``v'`` is outside every velocity obstacle that
could bring A within ``r`` of an obstacle before ``τ_o ≥ Δt``.
``tests/avoidance/test_orca_obstacles.py`` backs this with random walled scenes (convex
and non-convex polygons, thin boxes, radius and speed drawn per robot, fallbacks).
When the obstacle lines alone are infeasible (A wedged where its disc barely fits), the
fallback minimises their largest violation too, and nothing is guaranteed.

**Where the lines go.** The obstacle lines come first in the 2-D program and stay hard
constraints in the 3-D fallback (Sec. 5.2), which relaxes only the agents' lines, as RVO2
does: a robot gives up reciprocity before it gives up an obstacle.

**Neighbour query.** The edges are bucketed once into a uniform grid of side ``h ≥ R``
(:class:`EdgeGrid`, each edge in every cell its bounding box touches; cached per ``h``),
so a robot reads the edges of the at most 3×3 cells its range box touches, and an edge
listed in several of them is taken only in the first (the lowest cell of the overlap of
its box and the range box) — O(edges nearby) per robot, not O(all edges); the buffers of
one robot hold the most edges any 3×3 block of cells lists.

**Deviations from RVO2** (so equal inputs give equal lines but for these): RVO2 computes
in single precision; its obstacle tree splits an edge that crosses a splitting line into
two collinear pieces (one more convex vertex; the union of their velocity obstacles is the
edge's, but the nearest-first order and the covered test see two edges); and it orders
edges at equal distance (the two edges of a vertex nearest A) by its tree, not by index.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import NamedTuple

import numba
import numpy as np

from ..core import geometry
from ..core.errors import ConfigError

COVERED_TOL = 1e-5
"""Slack of the covered test (RVO2's ``RVO_EPSILON``) [m/s]."""
MAX_GRID_CELLS_PER_EDGE = 32
"""The grid has at most ``max(4096, 32 E)`` cells for E edges (``h`` grows otherwise)."""


class EdgeGrid(NamedTuple):
    """Edges bucketed into square cells of side ``h`` (cell ``(c_x, c_y)`` has key ``c_x · ny + c_y``)."""

    origin: np.ndarray  # (2,) lower corner of the edges' bounding box
    h: float
    nx: np.int64
    ny: np.int64
    start: np.ndarray  # (nx · ny + 1,) run of each cell in ``edges``
    edges: np.ndarray  # edge indices, cell by cell, increasing within a cell
    first_cell: np.ndarray  # (E, 2) lowest cell (c_x, c_y) of each edge's bounding box
    most: np.int64  # the most edges listed in any 3 × 3 block of cells: a bound on one robot's edges


class ObstacleEdges:
    """Polygon obstacles as ORCA reads them (see the module docstring).

    Parameters
    ----------
    solids:
        Polygons ``(V_k, 2)`` (any orientation, made counter-clockwise) that robots stay out of.
    enclosures:
        Polygons (made clockwise) that robots stay inside, e.g. the workspace bounds.

    Polygons need not be convex; consecutive repeated vertices are dropped.
    """

    def __init__(self, solids: Sequence[np.ndarray] = (), enclosures: Sequence[np.ndarray] = ()):
        rings = [geometry.ensure_ccw(_ring(p, f"solids[{k}]")) for k, p in enumerate(solids)]
        rings += [geometry.ensure_ccw(_ring(p, f"enclosures[{k}]"))[::-1] for k, p in enumerate(enclosures)]
        points, nxt, prv = [], [], []
        for ring in rings:
            base, v = sum(len(p) for p in points), len(ring)
            points.append(ring)
            nxt.append(base + (np.arange(v) + 1) % v)
            prv.append(base + (np.arange(v) - 1) % v)
        self.point = np.ascontiguousarray(np.concatenate(points) if points else np.zeros((0, 2)), dtype=np.float64)
        self.next = np.concatenate(nxt).astype(np.int64) if nxt else np.zeros(0, np.int64)
        self.previous = np.concatenate(prv).astype(np.int64) if prv else np.zeros(0, np.int64)
        edge = self.point[self.next] - self.point
        self.direction = np.ascontiguousarray(edge / np.hypot(edge[:, 0], edge[:, 1])[:, None])
        incoming = self.point - self.point[self.previous]
        turn = incoming[:, 0] * edge[:, 1] - incoming[:, 1] * edge[:, 0]
        self.convex = np.ascontiguousarray(turn >= 0.0)
        self._grids: dict[float, EdgeGrid] = {}

    @classmethod
    def from_workspace(cls, workspace) -> "ObstacleEdges":
        """The obstacles and the bounds of a :class:`~robofleet.core.workspace.Workspace`."""
        return cls(workspace.obstacles, [workspace.bounds])

    @property
    def count(self) -> int:
        """Number of edges."""
        return len(self.point)

    def grid(self, h: float) -> EdgeGrid:
        """The edges bucketed into cells of side ``≥ h`` (built once per ``h``)."""
        if h not in self._grids:
            self._grids[h] = _build_grid(self.point, self.next, float(h))
        return self._grids[h]

    def arrays(self, reach: float) -> tuple:
        """Everything the compiled step reads, for robots whose range is at most ``reach``."""
        g = self.grid(reach) if self.count else EdgeGrid(np.zeros(2), 1.0, np.int64(0), np.int64(0), np.zeros(1, np.int64),
                                                         np.zeros(0, np.int64), np.zeros((0, 2), np.int64), np.int64(0))
        return (self.point, self.next, self.previous, self.direction, self.convex, g.origin, float(g.h), np.int64(g.nx), np.int64(g.ny),
                g.start, g.edges, g.first_cell, np.int64(g.most))


@functools.cache
def no_obstacles() -> tuple:
    """The compiled step's obstacle arrays when there are none."""
    return ObstacleEdges().arrays(1.0)


def _ring(polygon, name: str) -> np.ndarray:
    p = np.asarray(polygon, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or not np.all(np.isfinite(p)):
        raise ConfigError(f"obstacles.{name}: expected a polygon of finite (x, y) vertices, received shape {p.shape}")
    keep = np.any(p != np.roll(p, 1, axis=0), axis=1) if len(p) > 1 else np.ones(len(p), bool)
    p = p[keep]
    if len(p) < 3:
        raise ConfigError(f"obstacles.{name}: expected a polygon of at least 3 distinct vertices, received {len(p)}")
    return p


def _build_grid(point: np.ndarray, nxt: np.ndarray, h: float) -> EdgeGrid:
    """Bucket every edge into the cells its bounding box touches (see :class:`EdgeGrid`)."""
    lo_pt, hi_pt = np.minimum(point, point[nxt]), np.maximum(point, point[nxt])
    origin, top = lo_pt.min(axis=0), hi_pt.max(axis=0)
    limit = max(4096, MAX_GRID_CELLS_PER_EDGE * len(point))
    while True:
        nx, ny = (np.floor((top - origin) / h).astype(np.int64) + 1).tolist()
        if nx * ny <= limit:
            break
        h *= 2.0
    first = np.floor((lo_pt - origin) / h).astype(np.int64)
    last = np.minimum(np.floor((hi_pt - origin) / h).astype(np.int64), [nx - 1, ny - 1])
    start = np.zeros(nx * ny + 1, np.int64)
    _fill_cells(first, last, ny, start, np.empty(0, np.int64), False)
    np.cumsum(start, out=start)
    edges = np.empty(start[-1], np.int64)
    _fill_cells(first, last, ny, start, edges, True)
    counts = np.pad(np.diff(start).reshape(nx, ny), 1)
    block = sum(counts[i : i + nx, j : j + ny] for i in range(3) for j in range(3))  # a robot's range box touches ≤ 3 × 3 cells
    return EdgeGrid(origin, h, np.int64(nx), np.int64(ny), start, edges, np.ascontiguousarray(first), np.int64(min(block.max(), len(point))))


@numba.njit(cache=True)
def _fill_cells(first, last, ny, start, edges, write):
    """Count the edges of each cell into ``start[c + 1]`` or (``write``, ``start`` the
    prefix sums) list them, in increasing edge order within a cell."""
    cursor = start[:-1].copy()
    for e in range(len(first)):
        for cx in range(first[e, 0], last[e, 0] + 1):
            for cy in range(first[e, 1], last[e, 1] + 1):
                c = cx * ny + cy
                if write:
                    edges[cursor[c]] = e
                    cursor[c] += 1
                else:
                    start[c + 1] += 1


# ---------------------------------------------------------------------------------------
# per robot, compiled: the neighbour edges and their lines
# ---------------------------------------------------------------------------------------
@numba.njit(cache=True)
def nearby_edges(px, py, reach, point, nxt, origin, h, nx, ny, start, edges, first_cell, dist, found):
    """Edges within ``reach`` (segment distance) with ``(px, py)`` strictly on their free
    side, nearest first (ties by edge index), into ``found``; returns their count."""
    if nx == 0:
        return 0
    x0, x1 = int(np.floor((px - reach - origin[0]) / h)), int(np.floor((px + reach - origin[0]) / h))
    y0, y1 = int(np.floor((py - reach - origin[1]) / h)), int(np.floor((py + reach - origin[1]) / h))
    if x1 < 0 or y1 < 0 or x0 >= nx or y0 >= ny:
        return 0
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, nx - 1), min(y1, ny - 1)
    count, reach_sq = 0, reach * reach
    for cx in range(x0, x1 + 1):
        for cy in range(y0, y1 + 1):
            c = cx * ny + cy
            for k in range(start[c], start[c + 1]):
                e = edges[k]
                if cx != max(first_cell[e, 0], x0) or cy != max(first_cell[e, 1], y0):
                    continue  # listed in an earlier cell of this query
                d2 = _facing_distance_sq(px, py, e, point, nxt)
                if d2 < reach_sq:
                    count = _insert_sorted(dist, found, count, d2, e)
    return count


@numba.njit(cache=True, inline="always")
def _facing_distance_sq(px, py, e, point, nxt):
    """Squared distance from ``p`` to edge ``e``, ``inf`` unless ``p`` is strictly on its right."""
    ax, ay = point[e, 0], point[e, 1]
    ex, ey = point[nxt[e], 0] - ax, point[nxt[e], 1] - ay
    rx, ry = px - ax, py - ay
    if ex * ry - ey * rx >= 0.0:  # on the line or on its left: the edge faces away
        return np.inf
    s = min(max((rx * ex + ry * ey) / (ex * ex + ey * ey), 0.0), 1.0)
    dx, dy = rx - s * ex, ry - s * ey
    return dx * dx + dy * dy


@numba.njit(cache=True, inline="always")
def _insert_sorted(dist, found, count, d2, e):
    j = count
    while j > 0 and (d2 < dist[j - 1] or (d2 == dist[j - 1] and e < found[j - 1])):
        dist[j], found[j] = dist[j - 1], found[j - 1]
        j -= 1
    dist[j], found[j] = d2, e
    return count + 1


@numba.njit(cache=True)
def obstacle_lines(px, py, vx, vy, r, tau, found, count, point, nxt, prv, unit, convex, lines):
    """The ORCA lines ``(q, n)`` (allowed: ``n·(v − q) ≥ 0``) of the edges ``found[:count]``
    for a robot at ``p`` with velocity ``v`` and radius ``r`` (module docstring), into
    ``lines[0 …]``; returns how many."""
    m = 0
    inv = 1.0 / tau
    for k in range(count):
        e = found[k]
        ax, ay = point[e, 0] - px, point[e, 1] - py
        bx, by = point[nxt[e], 0] - px, point[nxt[e], 1] - py
        if _covered(ax * inv, ay * inv, bx * inv, by * inv, r * inv, lines, m):
            continue
        m = _edge_line(ax, ay, bx, by, vx, vy, r, inv, e, nxt, prv, unit, convex, lines, m)
    return m


@numba.njit(cache=True, inline="always")
def _covered(cl0, cl1, cr0, cr1, rr, lines, m):
    """Whether both cut-off discs ``D(c, rr)`` lie beyond an earlier line by ``rr`` (± tolerance)."""
    for j in range(m):
        q0, q1, n0, n1 = lines[j, 0], lines[j, 1], lines[j, 2], lines[j, 3]
        if n0 * (cl0 - q0) + n1 * (cl1 - q1) <= -rr + COVERED_TOL and n0 * (cr0 - q0) + n1 * (cr1 - q1) <= -rr + COVERED_TOL:
            return True
    return False


@numba.njit(cache=True, inline="always")
def _put(lines, m, q0, q1, n0, n1):
    lines[m, 0], lines[m, 1], lines[m, 2], lines[m, 3] = q0, q1, n0, n1
    return m + 1


@numba.njit(cache=True, inline="always")
def _tangent(x, y, r, left):
    """Unit direction from the origin tangent to ``D((x, y), r)``, on the left or right of ``(x, y)``."""
    d2 = x * x + y * y
    leg = np.sqrt(d2 - r * r)
    s = r if left else -r
    return (x * leg - y * s) / d2, (x * s + y * leg) / d2


@numba.njit(cache=True)
def _edge_line(ax, ay, bx, by, vx, vy, r, inv, e, nxt, prv, unit, convex, lines, m):
    """Line of edge ``e`` (``a → b`` relative to the robot) appended at ``lines[m]``; returns the new count."""
    f = nxt[e]
    ex, ey = bx - ax, by - ay
    s = -(ax * ex + ay * ey) / (ex * ex + ey * ey)
    lx, ly = -ax - s * ex, -ay - s * ey
    line_sq, rr = lx * lx + ly * ly, r * r
    a_sq, b_sq = ax * ax + ay * ay, bx * bx + by * by
    # already in contact: push straight away from the nearest point
    if s < 0.0 and a_sq <= rr:
        return _put(lines, m, 0.0, 0.0, -ax / np.sqrt(a_sq), -ay / np.sqrt(a_sq)) if convex[e] else m
    if s > 1.0 and b_sq <= rr:
        next_edge_sees_it = bx * unit[f, 1] - by * unit[f, 0] < 0.0
        return _put(lines, m, 0.0, 0.0, -bx / np.sqrt(b_sq), -by / np.sqrt(b_sq)) if convex[f] and not next_edge_sees_it else m
    if 0.0 <= s <= 1.0 and line_sq <= rr:
        return _put(lines, m, 0.0, 0.0, unit[e, 1], -unit[e, 0])
    # the legs; v1, v2 the vertices they leave from (one vertex when seen obliquely)
    v1, v2 = e, f
    if s < 0.0 and line_sq <= rr:
        if not convex[e]:
            return m
        v2, bx, by = e, ax, ay
        left0, left1 = _tangent(ax, ay, r, True)
        right0, right1 = _tangent(ax, ay, r, False)
    elif s > 1.0 and line_sq <= rr:
        if not convex[f]:
            return m
        v1, ax, ay = f, bx, by
        left0, left1 = _tangent(bx, by, r, True)
        right0, right1 = _tangent(bx, by, r, False)
    else:
        left0, left1 = _tangent(ax, ay, r, True) if convex[e] else (-unit[e, 0], -unit[e, 1])
        right0, right1 = _tangent(bx, by, r, False) if convex[f] else (unit[e, 0], unit[e, 1])
    single = v1 == v2
    left_foreign = right_foreign = False
    before = prv[v1]
    if convex[v1] and left0 * unit[before, 1] - left1 * unit[before, 0] <= 0.0:  # left leg points into the previous edge
        left0, left1, left_foreign = -unit[before, 0], -unit[before, 1], True
    if convex[v2] and right0 * unit[v2, 1] - right1 * unit[v2, 0] <= 0.0:  # right leg points into the next edge
        right0, right1, right_foreign = unit[v2, 0], unit[v2, 1], True
    # project v on the boundary of the truncated velocity obstacle
    cl0, cl1, cr0, cr1 = ax * inv, ay * inv, bx * inv, by * inv
    cut0, cut1 = cr0 - cl0, cr1 - cl1
    t = 0.5 if single else ((vx - cl0) * cut0 + (vy - cl1) * cut1) / (cut0 * cut0 + cut1 * cut1)
    t_left = (vx - cl0) * left0 + (vy - cl1) * left1
    t_right = (vx - cr0) * right0 + (vy - cr1) * right1
    if (t < 0.0 and t_left < 0.0) or (single and t_left < 0.0 and t_right < 0.0):
        return _arc_line(vx - cl0, vy - cl1, cl0, cl1, r * inv, lines, m)
    if t > 1.0 and t_right < 0.0:
        return _arc_line(vx - cr0, vy - cr1, cr0, cr1, r * inv, lines, m)
    d_cut = np.inf if (t < 0.0 or t > 1.0 or single) else _sq(vx - cl0 - t * cut0, vy - cl1 - t * cut1)
    d_left = np.inf if t_left < 0.0 else _sq(vx - cl0 - t_left * left0, vy - cl1 - t_left * left1)
    d_right = np.inf if t_right < 0.0 else _sq(vx - cr0 - t_right * right0, vy - cr1 - t_right * right1)
    if d_cut <= d_left and d_cut <= d_right:  # the cut-off segment: the edge's outward normal
        n0, n1 = unit[v1, 1], -unit[v1, 0]
        return _put(lines, m, cl0 + r * inv * n0, cl1 + r * inv * n1, n0, n1)
    if d_left <= d_right:
        if left_foreign:
            return m
        n0, n1 = -left1, left0
        return _put(lines, m, cl0 + r * inv * n0, cl1 + r * inv * n1, n0, n1)
    if right_foreign:
        return m
    n0, n1 = right1, -right0
    return _put(lines, m, cr0 + r * inv * n0, cr1 + r * inv * n1, n0, n1)


@numba.njit(cache=True, inline="always")
def _sq(x, y):
    return x * x + y * y


@numba.njit(cache=True, inline="always")
def _arc_line(w0, w1, c0, c1, rr, lines, m):
    """Line tangent to the cut-off arc ``∂D(c, rr)`` at the point nearest ``v = c + w``."""
    w_len = np.sqrt(w0 * w0 + w1 * w1)
    n0, n1 = w0 / w_len, w1 / w_len
    return _put(lines, m, c0 + rr * n0, c1 + rr * n1, n0, n1)
