"""The three regular grids of Section 3 (Fig. 1), fitted to the search area.

Paper 002 (X. Yang, CCC 2017), Section 3: robots move along the edges of a regular
tessellation — equilateral triangles (T), squares (S) or regular hexagons (H) — with side
length ``a``. A vertex is *accessible* when a robot standing on it keeps the safety
radius ``r_safe`` from every obstacle and from the border (Fig. 2: ``v4`` lies within
``r_safe`` of the boundary and cannot be visited); an edge can be travelled when the whole
segment keeps that clearance (Section 4.1, step 2: an obstacle "blocking the way to the
neighbour").

Vertices are integer ids; every per-step query is a table look-up:

* ``points``       ``(V, 2)`` float64 coordinates,
* ``neighbours``   ``(V, k)`` int ids of the lattice neighbours one edge away, ``-1`` padded
  (``k`` = 6 / 4 / 3 for T / S / H),
* ``edge_ok``      ``(V, k)`` bool: the edge exists, both ends are accessible and the
  segment keeps ``r_safe`` clearance,
* ``block_distance`` ``(V, k)`` float: distance from the vertex to the nearest point of an
  obstacle or of the outside that blocks the edge (``inf`` for a free edge); a robot senses
  the blockage when this distance is at most ``r_so`` (see :mod:`.sensing`),
* ``priority``     ``(V,)`` int: rank of the vertex in the step-4 choice order.

Building a grid is O(V log V) with a cell list (:func:`robofleet.core.geometry.close_pairs_in_cells`)
plus vectorized shapely distance queries; it is done once per area and cached by callers.
Building and checking one loads no scipy (only :meth:`Grid.nearest_vertex` does).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from enum import Enum

import numpy as np
import shapely
from shapely.geometry import Polygon, box

from ..core.budget import HOW_TO_RAISE, format_bytes, memory_budget
from ..core.errors import ConfigError, short_repr
from ..core.geometry import close_pairs_in_cells
from ..core.workspace import Workspace

#: tolerance of length comparisons (equality conditions of Table 1 are used verbatim)
EPS = 1e-9


class GridKind(str, Enum):
    """The three regular tessellations of Fig. 1."""

    TRIANGULAR = "triangular"
    SQUARE = "square"
    HEXAGONAL = "hexagonal"


#: number of lattice neighbours of a vertex (the degree of the tessellation's vertex)
DEGREE = {GridKind.TRIANGULAR: 6, GridKind.SQUARE: 4, GridKind.HEXAGONAL: 3}


@dataclass(frozen=True, eq=False)
class Grid:
    """A regular grid fitted to a workspace (see the module docstring for the arrays)."""

    kind: GridKind
    a: float
    r_safe: float
    points: np.ndarray
    neighbours: np.ndarray
    accessible: np.ndarray
    edge_ok: np.ndarray
    block_distance: np.ndarray
    priority: np.ndarray
    workspace: Workspace

    @cached_property
    def edge_units(self) -> np.ndarray:
        """``(V, k, 2)`` unit vectors along each edge (zero for missing neighbours)."""
        vec = self.points[np.maximum(self.neighbours, 0)] - self.points[:, None, :]
        return np.where((self.neighbours >= 0)[:, :, None], vec / self.a, 0.0)

    @cached_property
    def edge_unit_headings(self) -> np.ndarray:
        """``(V, k)`` heading (``arctan2``) of each edge's unit vector (an LFP robot sliding along it)."""
        units = self.edge_units
        return np.arctan2(units[:, :, 1], units[:, :, 0])

    @cached_property
    def edge_headings(self) -> np.ndarray:
        """``(V, k)`` heading (``arctan2``) of each edge from its vertex (a robot turning to it)."""
        vec = self.points[self.candidates] - self.points[:, None, :]
        return np.arctan2(vec[:, :, 1], vec[:, :, 0])

    @cached_property
    def candidates(self) -> np.ndarray:
        """``neighbours`` with ``-1`` padding replaced by vertex 0 (masked by ``edge_ok`` / sensing)."""
        return np.maximum(self.neighbours, 0)

    @cached_property
    def candidate_words(self) -> tuple[np.ndarray, np.ndarray]:
        """Word index and bit mask of every candidate in a vertex bit set
        (see :mod:`~robofleet.search.knowledge`)."""
        cand = self.candidates
        return cand >> 6, np.uint64(1) << (cand & 63).astype(np.uint64)

    @cached_property
    def components(self) -> np.ndarray:
        """Connected-component label of every vertex in the graph of travellable edges."""
        src, slot = np.nonzero(self.edge_ok)
        return component_labels(self.n_vertices, src, self.neighbours[src, slot])

    @cached_property
    def n_components(self) -> int:
        """Number of connected components of the graph of travellable edges."""
        return int(self.components.max(initial=-1)) + 1

    @property
    def n_vertices(self) -> int:
        return len(self.points)

    @property
    def degree(self) -> int:
        return self.neighbours.shape[1]

    def nearest_vertex(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ids of the vertices nearest to ``points (m, 2)`` and their distances."""
        from scipy.spatial import cKDTree  # imported on use: building and checking a grid loads no scipy

        dist, idx = cKDTree(self.points).query(np.asarray(points, dtype=float).reshape(-1, 2))
        return idx.astype(np.intp), dist

    def reachable_from(self, starts: np.ndarray) -> np.ndarray:
        """Boolean mask of vertices reachable from ``starts`` along travellable edges."""
        labels = self.components
        holds_start = np.zeros(self.n_components, dtype=bool)
        holds_start[labels[np.asarray(starts, dtype=np.intp)]] = True
        return holds_start[labels]

    def border_vertices(self) -> np.ndarray:
        """Accessible vertices of the outermost accessible ring along the outer border.

        Assumption 2.2 places the robots "at different vertices along the border of the
        area": a vertex is on the border when its distance to the outer boundary is below
        ``a + r_safe`` (no accessible vertex lies between it and the border).
        """
        dist = chunked(self.workspace.boundary_distance, self.points)
        return np.flatnonzero(self.accessible & (dist < self.a + self.r_safe - EPS))


def lattice_points(kind: GridKind, a: float, origin: np.ndarray, extent: np.ndarray) -> np.ndarray:
    """Lattice points of ``kind`` with edge ``a`` anchored at ``origin``, covering ``extent``.

    ``extent`` is ``(width, height)`` measured from ``origin``. Triangular: rows ``a√3/2``
    apart, odd rows shifted by ``a/2``. Square: an ``a × a`` lattice. Hexagonal
    (honeycomb): a triangular Bravais lattice of constant ``a√3`` with two vertices per cell
    at ``(0, 0)`` and ``(0, a)``, so that every vertex has three neighbours at distance ``a``.
    """
    width, height = extent
    if kind is GridKind.SQUARE:
        xs = np.arange(0, width / a + 1 + EPS, dtype=float) * a
        ys = np.arange(0, height / a + 1 + EPS, dtype=float) * a
        gx, gy = np.meshgrid(xs, ys)
        pts = np.column_stack([gx.ravel(), gy.ravel()])
    elif kind is GridKind.TRIANGULAR:
        dy = a * np.sqrt(3.0) / 2.0
        rows = np.arange(0, int(np.floor(height / dy + EPS)) + 1)
        cols = np.arange(-1, int(np.ceil(width / a)) + 1)
        gc, gr = np.meshgrid(cols, rows)
        pts = np.column_stack([(gc + 0.5 * (gr % 2)).ravel() * a, gr.ravel() * dy])
    else:
        ex = a * np.sqrt(3.0)
        rows = np.arange(-1, int(np.ceil(height / (1.5 * a))) + 2)
        cols = np.arange(-1, int(np.ceil(width / ex)) + 2)
        gc, gr = np.meshgrid(cols, rows)
        base = np.column_stack([(gc + 0.5 * (gr % 2)).ravel() * ex, gr.ravel() * 1.5 * a])
        pts = np.concatenate([base, base + [0.0, a]])
    pts = pts[(pts[:, 0] >= -EPS) & (pts[:, 0] <= width + EPS) & (pts[:, 1] >= -EPS) & (pts[:, 1] <= height + EPS)]
    return pts + origin


def build_grid(workspace: Workspace, kind: GridKind | str, a: float, r_safe: float) -> Grid:
    """Fit a grid of ``kind`` with edge ``a`` to ``workspace``.

    The lattice is anchored at ``(xmin + r_safe, ymin + r_safe)`` so that the first row and
    column keep exactly the safety radius from a rectangular border; only lattice points
    inside the outer boundary belong to the grid (points inside obstacles stay, as
    inaccessible vertices, so that robots can record them as detected).

    Parameters
    ----------
    workspace:
        the search area ``A`` with its obstacles ``O_1 … O_l`` (Assumption 2.1).
    kind:
        ``triangular``, ``square`` or ``hexagonal``.
    a:
        edge length, > 0.
    r_safe:
        safety radius, ≥ 0.

    Raises
    ------
    ConfigError
        When ``a ≤ 0``, ``r_safe < 0`` or the area holds no lattice point.
    """
    kind = check_grid_arguments(workspace, kind, a, r_safe)
    xmin, ymin, xmax, ymax = workspace.extent
    origin = np.array([xmin + r_safe, ymin + r_safe])
    extent = np.array([xmax - xmin - r_safe, ymax - ymin - r_safe])
    pts = lattice_points(kind, a, origin, np.maximum(extent, 0.0))
    inside = shapely.intersects_xy(workspace.boundary_polygon, pts[:, 0], pts[:, 1])
    pts = pts[inside]
    if len(pts) == 0:
        raise ConfigError(f"grid: expected at least one lattice point inside the area, received none for a={a!r}")
    neighbours = neighbour_table(pts, a, DEGREE[kind])
    clearance = chunked(workspace.clearance, pts)
    accessible = clearance >= r_safe - EPS
    block = edge_block_distance(workspace, pts, neighbours, r_safe, clearance >= a * (1 + 2e-6) + r_safe)
    edge_ok = (neighbours >= 0) & np.isinf(block) & accessible[:, None] & accessible[np.maximum(neighbours, 0)]
    block = np.where(edge_ok, np.inf, block)
    return Grid(kind, float(a), float(r_safe), pts, neighbours, accessible, edge_ok, block, choice_priority(pts), workspace)


# -- input validation of build_grid ------------------------------------------------------
GRID_DENSITY = 1.16
"""Vertices per a² of the densest grid (triangular: 2/√3), for the memory budget."""
VERTEX_BYTES = 400
"""Memory of one grid vertex (point, neighbours, edge states, clearances, priorities)."""


def vertex_bound(width: float, height: float, a: float) -> float:
    """At most how many vertices a grid of edge ``a`` has in a ``width`` × ``height`` box."""
    return GRID_DENSITY * (width / a + 2) * (height / a + 2)


def check_grid_arguments(workspace: Workspace, kind: GridKind | str, a: float, r_safe: float) -> GridKind:
    """The grid kind, after one-line :class:`ConfigError` s for a workspace that is not one,
    an unknown kind, a non-positive ``a`` or ``r_safe < 0``, and a grid beyond the memory budget."""
    if not isinstance(workspace, Workspace):
        raise ConfigError(f"workspace: expected a Workspace, received {short_repr(workspace)}")
    try:
        kind = GridKind(kind)
    except ValueError:
        raise ConfigError(f"kind: expected one of {[k.value for k in GridKind]}, received {short_repr(kind)}") from None
    for name, value, positive in (("a", a, True), ("r_safe", r_safe, False)):
        number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
        if not (number and np.isfinite(value) and (value > 0 if positive else value >= 0)):
            what = "a positive edge length" if positive else "a non-negative radius"
            raise ConfigError(f"{name}: expected {what}, received {short_repr(value)}")
    xmin, ymin, xmax, ymax = workspace.extent
    vertices = vertex_bound(xmax - xmin, ymax - ymin, a)
    budget = memory_budget()
    if VERTEX_BYTES * vertices > budget:
        raise ConfigError(f"a: expected an edge length giving a grid within the memory budget of {format_bytes(budget)} "
                          f"(raise it with {HOW_TO_RAISE}), received {a!r}: up to {vertices:.3g} vertices")
    return kind


def neighbour_table(points: np.ndarray, a: float, degree: int) -> np.ndarray:
    """``(V, degree)`` ids of the points at distance ``a`` (``-1`` padded), ordered by angle.

    The pairs closer than ``a (1 + 10⁻⁶)``: a lattice's next-nearest points lie at least
    ``√2 a`` apart (``√3 a`` for triangles), so the tolerance only absorbs rounding."""
    pairs = close_pairs_in_cells(points, a * (1 + 1e-6))
    table = np.full((len(points), degree), -1, dtype=np.intp)
    if len(pairs) == 0:
        return table
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    d = points[dst] - points[src]
    order = np.lexsort((np.arctan2(d[:, 1], d[:, 0]), src))
    src, dst = src[order], dst[order]
    slot = np.arange(len(src)) - np.searchsorted(src, src)
    table[src, slot] = dst
    return table


def component_labels(n_vertices: int, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Connected-component label of every vertex of the undirected graph with edges
    ``src[e]``–``dst[e]``, the components numbered in the order of their smallest vertex.

    Hooking and shortcutting (Shiloach and Vishkin's scheme, minimum hooking only): every
    vertex points to a smaller or equal vertex of its component; each round hooks the
    larger root of every edge whose ends have different roots onto the smaller one, then
    shortcuts every pointer to its root. Pointers only decrease, so no cycle forms and the
    rounds end when both ends of every edge share a root; the smallest vertex of a
    component never gets hooked, so it is the root of all of it.
    """
    parent = np.arange(n_vertices)
    src, dst = np.asarray(src, dtype=np.intp), np.asarray(dst, dtype=np.intp)
    while True:
        a, b = parent[src], parent[dst]
        apart = a != b
        if not apart.any():
            break
        np.minimum.at(parent, np.maximum(a[apart], b[apart]), np.minimum(a[apart], b[apart]))
        while True:
            root = parent[parent]
            if np.array_equal(root, parent):
                break
            parent = root
    return np.unique(parent, return_inverse=True)[1].astype(np.int32)


def chunked(distance, points: np.ndarray, size: int = 1 << 16) -> np.ndarray:
    """``distance(points)`` evaluated ``size`` points at a time (bounded temporary memory)."""
    return np.concatenate([distance(points[i:i + size]) for i in range(0, len(points), size)] or [np.zeros(0)])


def edge_block_distance(workspace: Workspace, points: np.ndarray, neighbours: np.ndarray, r_safe: float,
                        clear: np.ndarray | None = None) -> np.ndarray:
    """Distance from each vertex to the nearest point blocking each of its edges.

    An edge ``(v, w)`` is blocked by every point of an obstacle or of the outside of the
    area that lies closer than ``r_safe`` to the segment ``vw`` (the robot would touch it
    while travelling). Returns ``(V, k)``: the distance from ``v`` to the nearest such
    point, ``inf`` for a free edge or a missing neighbour. ``clear (V,)`` may flag vertices
    whose clearance is at least the edge length plus ``r_safe``: every point of their edges
    keeps ``r_safe``, so only the other vertices' edges are measured (O(boundary), not O(V)).
    """
    out = np.full(neighbours.shape, np.inf)
    measured = neighbours >= 0 if clear is None else (neighbours >= 0) & ~clear[:, None]
    src, slot = np.nonzero(measured)
    if len(src) == 0:
        return out
    dst = neighbours[src, slot]
    xmin, ymin, xmax, ymax = workspace.extent
    pad = 10.0 * (r_safe + 1.0) + (xmax - xmin) + (ymax - ymin)
    outside = box(xmin - pad, ymin - pad, xmax + pad, ymax + pad).difference(workspace.boundary_polygon)
    solid = shapely.union_all([outside, *[Polygon(o) for o in workspace.obstacles]])
    segments = shapely.linestrings(np.stack([points[src], points[dst]], axis=1))
    near = shapely.distance(segments, solid) < r_safe - EPS
    if near.any():
        capsules = shapely.buffer(segments[near], r_safe, quad_segs=16)
        blockers = shapely.intersection(capsules, solid)
        starts = shapely.points(points[src[near]])
        dist = shapely.distance(starts, blockers)
        out[src[near], slot[near]] = dist
    return out


def choice_priority(points: np.ndarray) -> np.ndarray:
    """Rank of every vertex in the choice order of step 4 (higher rank chooses first).

    Section 4.1, step 4: robot ``j`` has priority over robot ``i`` when
    ``p_jx > p_ix`` or (``p_jy > p_iy`` and ``p_jx ≥ p_ix``) — the lexicographic order of
    ``(x, y)``. Coordinates are rounded to 1e-9 so that vertices of one lattice column
    compare as equal in ``x``.
    """
    key = np.round(points / 1e-9) * 1e-9
    order = np.lexsort((key[:, 1], key[:, 0]))
    rank = np.empty(len(points), dtype=np.intp)
    rank[order] = np.arange(len(points))
    return rank
