"""Route stage: sub-goals at visible vertices of the grown obstacles, a static visibility
roadmap with passages and exit points (docs/theory/buavc.md "Navigation stages").

The appendix-C obstacle branch (docs/theory/buavc.md "Deadlock heuristic") sends a stuck
robot to one vertex of the obstacle blocking it; behind a row of boxes that vertex can lead
into the next trap. Here each robot steers, from the start, towards the next vertex of its
shortest obstacle-free path. The obstacles are the known, static map that B-UAVC already
assumes (their nominal positions; the ε-shadow covers their uncertainty), so this costs no
communication and nothing about other robots: a robot uses only its own estimate, its goal
and the map.

* **Nodes** are the vertices of every obstacle grown by ``node_factor · c`` (round joins),
  with ``c`` the whole clearance the cells keep (r_s + the chance buffer + the ε-shadow),
  so a robot can reach them — leaving out those outside the workspace bounds shrunk by
  ``c`` and those inside another grown obstacle.
* **Visibility**: a segment is free when it does not cross the interior of any obstacle
  grown by ``sight_factor · c`` (less than the nodes' margin, so that the edges of a grown
  polygon and segments grazing it count as free). Convex obstacles are tested with the
  parametric clipping of a segment against half-planes (Cyrus & Beck 1978):
  ``x(t) = a + t (b − a)``, ``t ∈ [t_in, t_out]`` with ``t_in = max_{nₖ·d<0} −(nₖ·a − cₖ)/(nₖ·d)``,
  ``t_out = min_{nₖ·d>0} −(nₖ·a − cₖ)/(nₖ·d)``; the segment crosses when ``t_out > t_in``.
* **Exit points** (:func:`exit_points`): a robot that hugs its cell's obstacle face has its
  estimate inside a sight polygon much of the time, and from there every segment is
  blocked. Its segments, and a goal's, start where it leaves that polygon through the
  nearest face.
* **Passages** (:func:`gap_blockers`): a gap between two obstacles narrower than
  ``gap_factor (c + passage_sigmas σ)`` leaves the estimate no room to jitter in its cell;
  a thin wall along the shortest segment between the two obstacles closes it to every
  sight line.
* **Narrow passages as the last way** (:meth:`Roadmap.narrow_passages`): a goal whose only
  way from the robot runs through a closed gap that the cells can still pass (``2 c``
  wide or more) leaves the robot no visible node with a finite cost to go. Such a robot
  takes its sub-goal from a second roadmap whose passages close only the gaps narrower
  than ``2 c`` (no robot's cell fits there), until the first roadmap routes it again.
* **Cost to go** ``D_i(v)``: node-to-node shortest paths (Dijkstra from every node, once
  per workspace) closed with the free segments to each goal, once per run
  (:meth:`Roadmap.costs_to_goals`).
* **Sub-goal** each step: among the nodes and the goal visible from the estimate ``p̂``,
  the one minimising ``‖p̂ − v‖ + D_i(v)`` (the goal itself when it is visible and nearest;
  the previous sub-goal when nothing is visible, e.g. with the estimate inside a grown
  obstacle).

What the stage guarantees: the route's sub-goal only replaces the target the model's
cell-keeping controller is handed, so every command still keeps the next position inside
the robot's cell (the chance constraint is untouched); with nothing but static obstacles
in the way, the sub-goal's cost to go ``‖p̂ − v‖ + D_i(v)`` is the length of the shortest
free path on the roadmap, so a box between a robot and its goal is never a local minimum.
Measured effects: docs/results/avoidance.md "Measurements behind the navigation stages".
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numba
import numpy as np
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import Polygon
from shapely.ops import nearest_points

from ..kernels import use_parallel
from .params import RouteParams

_EPS = 1e-9


@dataclass(frozen=True)
class Halfplanes:
    """Convex obstacles as padded half-planes ``A x ≤ b`` (``(O, K, 2)``, ``(O, K)``);
    padding rows are ``0 · x ≤ 1`` (always true). ``lo``, ``hi`` ``(O, 2)``: the
    obstacles' bounding boxes when known (:func:`segments_free` then skips the pairs
    whose boxes miss the segment's)."""

    A: np.ndarray
    b: np.ndarray
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None


def grown_polygons(polygons: list[np.ndarray], margin: float) -> list[np.ndarray]:
    """Counter-clockwise vertices of each convex polygon grown by ``margin``: round joins
    of two segments per quarter turn, so every vertex lies at exactly ``margin`` (a mitred
    join would put the vertex of a sharp corner several margins away)."""
    out = []
    for p in polygons:
        grown = Polygon(p).buffer(margin, quad_segs=2)
        ring = np.asarray(grown.exterior.coords)[:-1]
        area2 = np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
        out.append(ring if area2 > 0 else ring[::-1])
    return out


def halfplanes(polygons: list[np.ndarray]) -> Halfplanes:
    """Outward half-planes of counter-clockwise convex polygons, padded to one width."""
    k = max((len(p) for p in polygons), default=1)
    A = np.zeros((len(polygons), k, 2))
    b = np.ones((len(polygons), k))
    for o, p in enumerate(polygons):
        edge = np.roll(p, -1, axis=0) - p
        normal = np.column_stack([edge[:, 1], -edge[:, 0]])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), _EPS)
        A[o, : len(p)], b[o, : len(p)] = normal, np.sum(normal * p, axis=1)
    lo = np.array([p.min(axis=0) for p in polygons]).reshape(-1, 2)
    hi = np.array([p.max(axis=0) for p in polygons]).reshape(-1, 2)
    return Halfplanes(A, b, lo, hi)


def segments_free(a: np.ndarray, b: np.ndarray, obstacles: Halfplanes) -> np.ndarray:
    """Whether each segment ``a[s] → b[s]`` misses the interior of every obstacle
    (``(S,)`` booleans; Cyrus–Beck clipping of ``a + t (b − a)``, ``t ∈ [0, 1]``): one
    compiled pass per segment, segments in parallel (:mod:`..kernels`).

    With the obstacles' bounding boxes known, only the obstacles whose boxes (grown by
    10⁻⁶ m) meet the segment's box are clipped: a segment that crosses an obstacle's
    interior by more than 10⁻⁶ m has points inside it, so inside its box."""
    if obstacles.A.shape[0] == 0 or len(a) == 0:
        return np.ones(len(a), bool)
    count = obstacles.A.shape[0]
    lo = np.full((count, 2), -np.inf) if obstacles.lo is None else obstacles.lo
    hi = np.full((count, 2), np.inf) if obstacles.hi is None else obstacles.hi
    out = np.empty(len(a), np.bool_)
    f64 = lambda x: np.ascontiguousarray(x, dtype=np.float64)  # noqa: E731
    args = (f64(a), f64(b), f64(obstacles.A), f64(obstacles.b), f64(lo), f64(hi), out)
    if use_parallel(len(a)):
        _segments_free_parallel(*args)
    else:
        _segments_free_range(0, len(a), *args)
    return out


_SEGMENT_CHUNK = 1024  # segments per parallel task
_BOX_PAD = 1e-6  # [m] the obstacles' boxes grown by the crossing length that counts


@numba.njit(cache=True, parallel=True)
def _segments_free_parallel(a, b, A, c, lo, hi, out):
    n = len(a)
    for chunk in numba.prange((n + _SEGMENT_CHUNK - 1) // _SEGMENT_CHUNK):
        _segments_free_range(chunk * _SEGMENT_CHUNK, min(n, (chunk + 1) * _SEGMENT_CHUNK), a, b, A, c, lo, hi, out)


@numba.njit(cache=True)
def _segments_free_range(first, last, a, b, A, c, lo, hi, out):
    """:func:`segments_free` for segments ``first … last − 1``: obstacles whose box misses
    the segment's are skipped; for the others, with ``n·a − c`` and ``n·d`` rounded as
    ``einsum`` rounds them, ``t_in`` the largest of the entering rows' ``t`` and 0 for the
    others (NaN if any is NaN, as ``np.max``), ``t_out`` likewise the smallest with 1; a
    segment crosses an obstacle when no row holds it outside while parallel and
    ``(t_out − t_in) ‖d‖ > 1e-6``."""
    for s in range(first, last):
        a0, a1 = a[s, 0], a[s, 1]
        d0, d1 = b[s, 0] - a0, b[s, 1] - a1
        x_lo, x_hi, y_lo, y_hi = min(a0, b[s, 0]), max(a0, b[s, 0]), min(a1, b[s, 1]), max(a1, b[s, 1])
        length = np.sqrt(d0 * d0 + d1 * d1)
        free = True
        for o in range(A.shape[0]):
            if x_lo > hi[o, 0] + _BOX_PAD or x_hi < lo[o, 0] - _BOX_PAD or y_lo > hi[o, 1] + _BOX_PAD or y_hi < lo[o, 1] - _BOX_PAD:
                continue
            t_in, t_out, outside_parallel = -np.inf, np.inf, False
            for k in range(A.shape[1]):
                na = (A[o, k, 0] * a0 + A[o, k, 1] * a1) - c[o, k]
                nd = A[o, k, 0] * d0 + A[o, k, 1] * d1
                entering, leaving = nd < -_EPS, nd > _EPS
                low = -na / nd if entering else 0.0
                high = -na / nd if leaving else 1.0
                t_in = np.nan if (low != low or t_in != t_in) else max(t_in, low)
                t_out = np.nan if (high != high or t_out != t_out) else min(t_out, high)
                outside_parallel |= abs(nd) <= _EPS and na >= -_EPS
            if not outside_parallel and (t_out - t_in) * length > 1e-6:
                free = False
                break
        out[s] = free


def exit_points(points: np.ndarray, planes: Halfplanes) -> np.ndarray:
    """Each point moved out of every polygon of ``planes`` that holds it, through that
    polygon's nearest face, polygon by polygon (points outside them are unchanged)."""
    out = np.array(points, float)
    if len(out) == 0:
        return out
    for A, b in zip(planes.A, planes.b):
        slack = out @ A.T - b  # (S, K), all < 0 inside
        inside = np.all(slack < -1e-9, axis=1)
        if inside.any():
            face = np.argmax(slack[inside], axis=1)
            depth = -slack[inside, face]
            out[inside] += (depth + 1e-6)[:, None] * A[face]
    return out


def gap_blockers(polygons: list[np.ndarray], width: float, thickness: float = 0.01) -> list[np.ndarray]:
    """Counter-clockwise thin rectangles across every gap narrower than ``width`` between
    two of the convex ``polygons``: along the shortest segment between them, reaching a
    little into both. A path through such a gap crosses that segment, so no sight line
    passes (O(O²) pairs: maps have few obstacles)."""
    shapes = [Polygon(p) for p in polygons]
    out = []
    for i, j in combinations(range(len(shapes)), 2):
        gap = shapes[i].distance(shapes[j])
        if not 0.0 < gap < width:
            continue
        p, q = (np.asarray(point.coords[0]) for point in nearest_points(shapes[i], shapes[j]))
        along = (q - p) / gap
        side = np.array([-along[1], along[0]]) * thickness / 2
        a, b = p - thickness * along, q + thickness * along
        out.append(np.array([a - side, b - side, b + side, a + side]))
    return out


_NO_PLANES = Halfplanes(np.zeros((0, 1, 2)), np.zeros((0, 1)))


class Roadmap:
    """The visibility roadmap of one workspace (module docstring).

    Parameters
    ----------
    polygons:
        The obstacles' nominal convex polygons (each ``(V, 2)``).
    margin:
        How far the nodes lie from the obstacles [m].
    bounds:
        ``(x_min, y_min, x_max, y_max)`` of the workspace.
    clearance:
        How far the cells keep robots from the obstacles and the walls [m].
    passage:
        The margin [m] for the estimate's noise (module docstring, "Passages"): gaps
        narrower than ``gap_factor (clearance + passage)`` are closed to sight lines.
    sight_factor, gap_factor:
        As in :class:`RouteParams`.

    Notes
    -----
    The polygons, the clearance and the passage rule (``passage``, ``gap_factor``) are kept
    as attributes: the detour stage closes the gaps beside still neighbours by the same rule.
    """

    def __init__(self, polygons: list[np.ndarray], margin: float, bounds: tuple[float, float, float, float], clearance: float,
                 passage: float = 0.0, sight_factor: float = RouteParams.sight_factor, gap_factor: float = RouteParams.gap_factor):
        self.polygons, self.clearance, self.passage, self.gap_factor = polygons, clearance, passage, gap_factor
        self.margin, self.bounds, self.sight_factor = margin, bounds, sight_factor
        grown = grown_polygons(polygons, margin)
        self.grown_planes = halfplanes(grown) if grown else _NO_PLANES
        sight = grown_polygons(polygons, sight_factor * clearance) + gap_blockers(polygons, gap_factor * (clearance + passage))
        self.sight = halfplanes(sight) if polygons else _NO_PLANES
        nodes = np.concatenate(grown) if grown else np.zeros((0, 2))
        lo, hi = np.asarray(bounds[:2]) + clearance, np.asarray(bounds[2:]) - clearance
        self.lower, self.upper = lo, hi
        keep = np.all((nodes >= lo) & (nodes <= hi), axis=1) & ~self._inside_grown(nodes, grown)
        self.nodes = nodes[keep]
        self.node_edges = self._visibility(self.nodes, self.nodes)
        self.node_paths = self._shortest_paths(self.node_edges)

    def narrow_passages(self) -> Roadmap:
        """The same roadmap with only the gaps no cell can pass closed: narrower than
        ``2 c`` (no noise margin). A cell keeps the robot ``c`` from both obstacles of a
        gap, so a gap at least ``2 c`` wide is passable, however tightly."""
        return Roadmap(self.polygons, self.margin, self.bounds, self.clearance, 0.0, self.sight_factor, 2.0)

    @staticmethod
    def _inside_grown(points: np.ndarray, grown: list[np.ndarray]) -> np.ndarray:
        """Points strictly inside some grown obstacle (a vertex lies on its own boundary)."""
        if not grown or len(points) == 0:
            return np.zeros(len(points), bool)
        planes = halfplanes(grown)
        slack = np.einsum("okc,sc->sok", planes.A, points) - planes.b[None]
        return np.any(np.all(slack < -1e-6, axis=2), axis=1)

    @staticmethod
    def _shortest_paths(edges: np.ndarray) -> np.ndarray:
        """``(V, V)`` shortest path lengths over the free node-to-node segments."""
        if len(edges) == 0:
            return np.zeros((0, 0))
        graph = np.where(np.isfinite(edges), np.maximum(edges, _EPS), 0.0)
        np.fill_diagonal(graph, 0.0)
        return dijkstra(graph, directed=False)

    def _visibility(self, a: np.ndarray, b: np.ndarray, seen_b: np.ndarray | None = None) -> np.ndarray:
        """``(len(a), len(b))`` lengths of free segments, ``inf`` where blocked; the
        segments are tested to ``seen_b`` (default ``b``)."""
        if len(a) == 0 or len(b) == 0:
            return np.full((len(a), len(b)), np.inf)
        seen_b = b if seen_b is None else seen_b
        ia, ib = np.repeat(np.arange(len(a)), len(b)), np.tile(np.arange(len(b)), len(a))
        free = segments_free(a[ia], seen_b[ib], self.sight)
        length = np.linalg.norm(a[ia] - b[ib], axis=1)
        return np.where(free, length, np.inf).reshape(len(a), len(b))

    def costs_to_goals(self, goals: np.ndarray) -> np.ndarray:
        """``D[i, v]``: length of the shortest free path from node ``v`` to goal ``i``
        (``inf`` if none): ``min_u (d(v, u) + ‖u − g_i‖)`` over the nodes ``u`` that see
        the goal, with ``d`` the node-to-node shortest paths (one Dijkstra from every
        node, computed once for all goals)."""
        if len(self.nodes) == 0:
            return np.full((len(goals), 0), np.inf)
        to_goal = self._visibility(self.nodes, goals, exit_points(goals, self.sight))  # (V, N)
        return np.min(self.node_paths[:, :, None] + to_goal[None, :, :], axis=1).T

    def subgoals(self, estimates: np.ndarray, goals: np.ndarray, costs: np.ndarray,
                 seen_goals: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each robot's sub-goal ``(N, 2)`` — the visible node or goal minimising
        ``‖p̂ − v‖ + D_i(v)`` (module docstring) —, the path length ``D_i`` left after it
        (0 for the goal) and whether anything was visible at all. Segments start and end
        where the estimate and the goal leave the sight polygons (:func:`exit_points`;
        ``seen_goals``, the goals' exit points, when the caller keeps them).

        Only robots that do not see their goal look at the nodes, and each tests its nodes
        in order of ``‖p̂ − v‖ + D_i(v)`` (:meth:`best_visible_nodes`), so the first visible
        one is the minimiser: the same sub-goal as testing every node, for a few tests."""
        n, n_nodes = len(estimates), len(self.nodes)
        seen_from = exit_points(estimates, self.sight)
        seen_goals = exit_points(goals, self.sight) if seen_goals is None else seen_goals
        goal_free = segments_free(seen_from, seen_goals, self.sight)
        if n_nodes == 0:
            return goals.copy(), np.zeros(n), np.ones(n, bool)
        total = np.linalg.norm(estimates[:, None] - self.nodes[None], axis=2) + costs
        best, found = self.best_visible_nodes(seen_from, total, ~goal_free)
        use_node = ~goal_free & found
        sub = np.where(use_node[:, None], self.nodes[best], goals)
        return sub, np.where(use_node, costs[np.arange(n), best], 0.0), goal_free | found

    def best_visible_nodes(self, seen_from: np.ndarray, total: np.ndarray, wanted: np.ndarray,
                           chunk: int = 8) -> tuple[np.ndarray, np.ndarray]:
        """For each ``wanted`` robot, the node minimising ``total`` ``(N, V)`` among those
        free to see from ``seen_from`` (the lowest index among equal totals, as
        ``argmin``), and whether one was found. Nodes are tested ``chunk`` at a time in
        ascending (stable) order of ``total``; a robot stops at its first visible node
        (every later node has a total at least as large) or at its first infinite total."""
        n = len(total)
        best, found = np.zeros(n, np.intp), np.zeros(n, bool)
        rows = np.flatnonzero(wanted)
        if len(rows) == 0:
            return best, found
        order = np.argsort(total[rows], axis=1, kind="stable")
        for start in range(0, total.shape[1], chunk):
            cols = order[:, start:start + chunk]
            finite = np.isfinite(total[rows[:, None], cols])
            free = segments_free(np.repeat(seen_from[rows], cols.shape[1], axis=0), self.nodes[cols.ravel()],
                                 self.sight).reshape(cols.shape) & finite
            hit = free.any(axis=1)
            best[rows[hit]] = cols[hit, np.argmax(free[hit], axis=1)]
            found[rows[hit]] = True
            going = ~hit & finite.all(axis=1)
            rows, order = rows[going], order[going]
            if len(rows) == 0:
                break
        return best, found


class Route:
    """One team's route stage: its roadmap and its goals' costs to go, computed once.

    :meth:`step` returns each robot's sub-goal and its estimated remaining path length
    ``‖p̂ − v‖ + D_i(v)`` (the straight distance when the goal is visible), the progress
    measure the progress checker uses instead of the straight distance to the goal.
    A robot for which the roadmap finds no way takes the :meth:`Roadmap.narrow_passages`
    roadmap's sub-goal (module docstring), built the first time one is needed.
    """

    def __init__(self, roadmap: Roadmap, goals: np.ndarray):
        self.roadmap, self.goals = roadmap, goals
        self.costs = roadmap.costs_to_goals(goals)
        self.seen_goals = exit_points(goals, roadmap.sight)  # the goals do not move
        self.last = goals.copy(), np.zeros(len(goals))
        self._narrow: tuple[Roadmap, np.ndarray, np.ndarray] | None = None

    def narrow(self) -> tuple[Roadmap, np.ndarray, np.ndarray]:
        """The narrow-passage roadmap, its costs to the goals and the goals' exit points."""
        if self._narrow is None:
            roadmap = self.roadmap.narrow_passages()
            self._narrow = roadmap, roadmap.costs_to_goals(self.goals), exit_points(self.goals, roadmap.sight)
        return self._narrow

    def step(self, estimates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sub-goals and remaining path lengths; a robot for which the roadmap finds no way
        takes the narrow-passage roadmap's, and one that sees nothing on either (its
        estimate inside a grown obstacle) keeps its previous sub-goal."""
        sub, rest, seen = self.roadmap.subgoals(estimates, self.goals, self.costs, self.seen_goals)
        lost = np.flatnonzero(~seen)
        if len(lost):
            roadmap, costs, seen_goals = self.narrow()
            sub[lost], rest[lost], seen[lost] = roadmap.subgoals(estimates[lost], self.goals[lost], costs[lost], seen_goals[lost])
        sub, rest = np.where(seen[:, None], sub, self.last[0]), np.where(seen, rest, self.last[1])
        self.last = sub, rest
        return sub, np.linalg.norm(sub - estimates, axis=1) + rest
