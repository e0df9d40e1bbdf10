"""Sub-goals at visible vertices of the grown obstacles: a static visibility roadmap
(the "sub-goals on the cell boundary / at obstacle vertices" idea, made
global).

The appendix-C obstacle branch (docs/theory/buavc.md "Deadlock heuristic") sends a stuck robot
to one vertex of the obstacle blocking it; behind a row of boxes that vertex can lead into
the next trap. Here each robot steers, from the start, towards the next vertex of its
shortest obstacle-free path. The obstacles are the known, static map that B-UAVC already
assumes (their nominal positions; the ε-shadow covers their uncertainty), so this costs
no communication and nothing about other robots: a robot uses only its own estimate, its
goal and the map.

* **Nodes** are the vertices of every obstacle grown by ``margin`` (round joins) — a little
  more than the whole clearance the cells keep (r_s + the chance buffer + the ε-shadow),
  so a robot can reach them — leaving out those outside the workspace bounds shrunk by
  the same clearance and those inside another grown obstacle.
* **Visibility**: a segment is free when it does not cross the interior of any obstacle
  grown by ``sight_margin`` (less than ``margin``, so that the edges of a grown polygon
  and segments grazing it count as free). Convex obstacles are tested with the
  parametric clipping of a segment against half-planes (Cyrus & Beck 1978).
* **Seeing from inside the band** (:func:`exit_points`): a robot that hugs its cell's
  obstacle face has its estimate inside a sight polygon much of the time, and from
  there every segment is blocked. Its segments, and a goal's, start at the point where
  it leaves that polygon through the nearest face. Without this such a robot saw
  nothing, kept steering to a goal behind the obstacle and slid to and fro along the
  face (measured: the commonest of the remaining random-scenario failures).
* **Passages** (:func:`gap_blockers`): a gap between two obstacles narrower than
  ``1.8 (clearance + passage)``, with ``passage`` a margin for the estimate's noise
  (``liveness.passage_sigmas`` σ, set by the simulation), leaves the estimate no room to
  jitter in its cell; a thin wall across it, along the shortest segment between the two
  obstacles, closes it to every sight line. Elsewhere nodes and sight lines stay where
  the cells' clearance puts them.
* **Cost to go** ``D_i(v)``: node-to-node shortest paths (Dijkstra from every node,
  once per workspace) closed with the free segments to each goal, once per run
  (:meth:`Roadmap.costs_to_goals`).
* **Sub-goal** each step: among the nodes and the goal visible from the estimate ``p̂``,
  the one minimising ``‖p̂ − v‖ + D_i(v)`` (the goal itself when it is visible and
  nearest; the goal, too, when nothing is visible, e.g. with the estimate inside a
  grown obstacle).

The sub-goal only replaces the goal that the controller projects onto the cell, so every
command still keeps the next position inside the robot's cell (the chance constraint is
untouched).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import Polygon
from shapely.ops import nearest_points

_EPS = 1e-9


@dataclass(frozen=True)
class Halfplanes:
    """Convex obstacles as padded half-planes ``A x ≤ b`` (``(O, K, 2)``, ``(O, K)``);
    padding rows are ``0 · x ≤ 1`` (always true)."""

    A: np.ndarray
    b: np.ndarray


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
    return Halfplanes(A, b)


def segments_free(a: np.ndarray, b: np.ndarray, obstacles: Halfplanes) -> np.ndarray:
    """Whether each segment ``a[s] → b[s]`` misses the interior of every obstacle
    (``(S,)`` booleans; Cyrus–Beck clipping of ``a + t (b − a)``, ``t ∈ [0, 1]``)."""
    if obstacles.A.shape[0] == 0:
        return np.ones(len(a), bool)
    d = b - a
    na = np.einsum("okc,sc->sok", obstacles.A, a) - obstacles.b[None]  # n·a − c  (S, O, K)
    nd = np.einsum("okc,sc->sok", obstacles.A, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -na / nd
    entering, leaving = nd < -_EPS, nd > _EPS
    t_lo = np.max(np.where(entering, t, 0.0), axis=2)
    t_hi = np.min(np.where(leaving, t, 1.0), axis=2)
    outside_parallel = np.any((np.abs(nd) <= _EPS) & (na >= -_EPS), axis=2)
    length = np.linalg.norm(d, axis=1)[:, None]
    crosses = ~outside_parallel & ((t_hi - t_lo) * length > 1e-6)
    return ~np.any(crosses, axis=1)


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
        narrower than ``1.8 (clearance + passage)`` are closed to sight lines.
    """

    def __init__(self, polygons: list[np.ndarray], margin: float, bounds: tuple[float, float, float, float], clearance: float,
                 passage: float = 0.0):
        grown = grown_polygons(polygons, margin)
        self.grown_planes = halfplanes(grown) if grown else _NO_PLANES
        sight = grown_polygons(polygons, 0.9 * clearance) + gap_blockers(polygons, 1.8 * (clearance + passage))
        self.sight = halfplanes(sight) if polygons else _NO_PLANES
        nodes = np.concatenate(grown) if grown else np.zeros((0, 2))
        lo, hi = np.asarray(bounds[:2]) + clearance, np.asarray(bounds[2:]) - clearance
        self.lower, self.upper = lo, hi
        keep = np.all((nodes >= lo) & (nodes <= hi), axis=1) & ~self._inside_grown(nodes, grown)
        self.nodes = nodes[keep]
        self.node_edges = self._visibility(self.nodes, self.nodes)
        self.node_paths = self._shortest_paths(self.node_edges)

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
        ``seen_goals``, the goals' exit points, when the caller keeps them)."""
        n, n_nodes = len(estimates), len(self.nodes)
        seen_from = exit_points(estimates, self.sight)
        seen_goals = exit_points(goals, self.sight) if seen_goals is None else seen_goals
        goal_free = segments_free(seen_from, seen_goals, self.sight)
        if n_nodes == 0:
            return goals.copy(), np.zeros(n), np.ones(n, bool)
        ia = np.repeat(np.arange(n), n_nodes)
        free = segments_free(seen_from[ia], np.tile(self.nodes, (n, 1)), self.sight).reshape(n, n_nodes)
        total = np.where(free, np.linalg.norm(estimates[:, None] - self.nodes[None], axis=2) + costs, np.inf)
        best = np.argmin(total, axis=1)
        found = np.isfinite(total[np.arange(n), best])
        use_node = ~goal_free & found
        sub = np.where(use_node[:, None], self.nodes[best], goals)
        return sub, np.where(use_node, costs[np.arange(n), best], 0.0), goal_free | found


class Navigation:
    """One team's use of the roadmap: its goals' costs to go, computed once.

    :meth:`step` returns each robot's sub-goal and its estimated remaining path length
    ``‖p̂ − v‖ + D_i(v)`` (the straight distance when the goal is visible), the progress
    measure the deadlock detection uses instead of the straight distance to the goal.
    """

    def __init__(self, roadmap: Roadmap, goals: np.ndarray, detours=None):
        self.roadmap, self.goals, self.detours = roadmap, goals, detours
        self.costs = roadmap.costs_to_goals(goals)
        self.seen_goals = exit_points(goals, roadmap.sight)  # the goals do not move
        self.last = goals.copy(), np.zeros(len(goals))

    def step(self, estimates: np.ndarray, arrived: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Sub-goals and remaining path lengths; a robot that sees nothing (its estimate
        inside a grown obstacle) keeps its previous sub-goal. With ``detours``
        (:class:`.detour.Detours`) and ``arrived`` given, blocked robots re-plan around
        the neighbours that hold still."""
        sub, rest, seen = self.roadmap.subgoals(estimates, self.goals, self.costs, self.seen_goals)
        sub, rest = np.where(seen[:, None], sub, self.last[0]), np.where(seen, rest, self.last[1])
        self.last = sub, rest
        to_go = np.linalg.norm(sub - estimates, axis=1) + rest
        if self.detours is None or arrived is None:
            return sub, to_go
        return self.detours.apply(estimates, arrived, sub, to_go)
