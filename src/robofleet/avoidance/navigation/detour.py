"""Detour stage: re-plan around neighbours that hold still (docs/theory/buavc.md
"Navigation stages").

The route stage's static roadmap (:mod:`.route`) knows only the map. A parked robot that sits in
the gap between two obstacles, or a robot stuck there, closes that gap as surely as an
obstacle would, yet the roadmap keeps sending the robots behind it into the gap. Here a
*blocked* robot treats the neighbours it sees holding still as temporary obstacles and
re-plans on the visibility graph (Lozano-Pérez & Wesley 1979, the idea behind the static
roadmap) with a disc around each of them; when a still neighbour closes a gap, the route
goes round the other way. The idea and its thresholds are ours; all of it is
decentralized and communication-free:

* **Still** (:class:`.yielding.StillTracker`): an estimate that stays within ``still_radius`` of its
  running mean (time constant ``still_steps / 2``) for ``still_steps`` consecutive steps,
  the test the yielding rule uses for parked robots (:class:`.yielding.ParkingState`).
  A robot applies it to its own estimate (am I blocked?) and to the estimates of the
  neighbours in its local box R_loc (who holds still?).
* **Blocked**: a robot that has not arrived, whose own estimate has held still for
  ``block_steps`` steps, with a still neighbour in its local box. It then re-plans for
  ``detour_steps`` steps (so the detour survives the robot's moving off), and stops as
  soon as no still neighbour is left in its box (the neighbour moved, or is behind it).
* **Re-plan** (:func:`detour_subgoal`): the static nodes outside the discs plus the
  vertices of each disc grown a little, the same visibility test as the roadmap, one
  Dijkstra from the estimate to the goal; the sub-goal is the first node of that path.
  The disc radius is the pair clearance ``2 β`` the cells keep between two estimates;
  a neighbour closer than that to the goal is left out (it is parked on or near the
  goal and the yielding rule moves it).
* **Anchored discs**: each disc is centred on the still neighbour's running mean (the
  still test's mean, :class:`.yielding.StillTracker`), not on its latest estimate. A
  still neighbour's estimate jitters by σ per step and its mean (weight
  ``α = 2 / still_steps`` per step) by ``σ √(α / (2 − α))``, about σ/7 at the shipped 50
  steps, so a gap the disc nearly closes does not open and close from step to step,
  sending the sub-goal from one side of the neighbour to the other.
* **Passages** (:func:`passage_walls`): the route's passage rule
  (:func:`.route.gap_blockers`) applied to the still neighbours. The cells keep a
  robot's estimate ``2 β`` from a neighbour's and ``c`` from an obstacle, so for a
  robot passing by, a neighbour is an obstacle of radius ``2 β − c``; a gap narrower
  than ``gap_factor (c + passage)`` between such a disc and an obstacle, or between two
  such discs, gets a thin wall across it. Without the walls a sight line passes
  wherever the sight discs (``sight_factor · 2 β``) and the obstacles' sight polygons
  (``sight_factor · c``) leave a sliver, which is up to ``(1 − sight_factor)(2 β + c)``
  narrower than the robot needs, with no room for the noise.

What the stage guarantees: the detour sub-goal only replaces the route's sub-goal, which
the model's cell-keeping controller keeps inside the cell (the chance constraint is
untouched); a detour lasts at most ``steps`` steps; the path it follows is the shortest on
the visibility graph of the map, the discs and the passage walls, so with the still
neighbours as they are it reaches the goal whenever that graph connects them; a wall
closes only a gap narrower than the route's passage width, with the neighbour counted as
an obstacle of radius ``2 β − c``. Single and double integrators use it;
unicycles do not (:mod:`.pipeline`). Only blocked robots re-plan, so the cost is a few
small graphs per step. Measured effects: docs/results/avoidance.md "Measurements behind the navigation stages".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree
from shapely.geometry import Point

from . import route
from .params import DetourParams, YieldingParams
from .route import Halfplanes, halfplanes, segments_free
from .yielding import StillTracker

_EPS = 1e-9


def disc_polygons(centres: np.ndarray, radius: np.ndarray | float) -> list[np.ndarray]:
    """Counter-clockwise octagons with vertices on the circles of ``radius`` about
    ``centres`` (two segments per quarter turn, as the roadmap's round joins)."""
    radii = np.broadcast_to(np.asarray(radius, float), (len(centres),))
    out = []
    for c, r in zip(centres, radii):
        ring = np.asarray(Point(c).buffer(r, quad_segs=2).exterior.coords)[:-1]
        area2 = np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
        out.append(ring if area2 > 0 else ring[::-1])
    return out


@dataclass(frozen=True)
class DetourGraph:
    """The visibility graph of one re-plan: ``points`` = [estimate, goal, nodes...],
    ``lengths`` of the free segments (``inf`` where blocked), the discs' sight polygons and
    the walls across the passages they close (:func:`passage_walls`)."""

    points: np.ndarray
    lengths: np.ndarray
    discs: list[np.ndarray]
    walls: list[np.ndarray]


def _inside(points: np.ndarray, planes: Halfplanes) -> np.ndarray:
    """Points strictly inside some polygon of ``planes``."""
    if planes.A.shape[0] == 0 or len(points) == 0:
        return np.zeros(len(points), bool)
    slack = np.einsum("okc,sc->sok", planes.A, points) - planes.b[None]
    return np.any(np.all(slack < -1e-6, axis=2), axis=1)


def _pair_lengths(a: np.ndarray, b: np.ndarray, planes: list[Halfplanes], seen_a=None, seen_b=None) -> np.ndarray:
    """``(len(a), len(b))`` lengths of segments free of every polygon set, ``inf`` else;
    ``seen_a``/``seen_b`` (default ``a``/``b``) are where the segments are tested from."""
    seen_a, seen_b = (a if seen_a is None else seen_a), (b if seen_b is None else seen_b)
    ia, ib = np.repeat(np.arange(len(a)), len(b)), np.tile(np.arange(len(b)), len(a))
    free = np.ones(len(ia), bool)
    for p in planes:
        free &= segments_free(seen_a[ia], seen_b[ib], p)
    return np.where(free, np.linalg.norm(a[ia] - b[ib], axis=1), np.inf).reshape(len(a), len(b))


def passage_walls(roadmap: route.Roadmap, centres: np.ndarray, radius: float) -> list[np.ndarray]:
    """Thin walls across the gaps too narrow to pass between a still neighbour (at
    ``centres``, pair clearance ``radius``) and an obstacle or another still neighbour:
    the route's passage rule (:func:`.route.gap_blockers`, closing gaps narrower than
    ``gap_factor (c + passage)``) with each neighbour an obstacle of radius
    ``radius − c`` (module docstring, "Passages")."""
    core = disc_polygons(centres, max(radius - roadmap.clearance, 1e-3))
    width = roadmap.gap_factor * (roadmap.clearance + roadmap.passage)
    walls = []
    for k, disc in enumerate(core):
        for other in core[k + 1:] + list(roadmap.polygons):
            walls += route.gap_blockers([disc, other], width)
    return walls


def detour_graph(roadmap: route.Roadmap, estimate: np.ndarray, goal: np.ndarray, centres: np.ndarray,
                 radius: float, params: DetourParams) -> DetourGraph:
    """The graph of :func:`detour_subgoal` for one robot: static nodes outside the
    discs' sight polygons plus each disc's vertices at ``node_factor · radius`` (inside
    the workspace, outside the grown obstacles and the other discs), with the passages the
    discs close walled off (:func:`passage_walls`). Static node pairs reuse the roadmap's
    visibility and are only tested against the discs and the walls."""
    sight_r = np.minimum(params.sight_factor * radius, 0.95 * np.linalg.norm(centres - estimate, axis=1))
    discs = disc_polygons(centres, sight_r)
    walls = passage_walls(roadmap, centres, radius)
    disc_planes = halfplanes(discs + walls)
    keep = ~_inside(roadmap.nodes, disc_planes)
    static = roadmap.nodes[keep]
    extra = np.concatenate(disc_polygons(centres, params.node_factor * radius))
    lo, hi = roadmap.lower, roadmap.upper
    ok = np.all((extra >= lo) & (extra <= hi), axis=1) & ~_inside(extra, roadmap.grown_planes) & ~_inside(extra, disc_planes)
    ends = np.vstack([estimate, goal, extra[ok]])
    seen = ends.copy()  # the estimate and the goal are seen from where they leave the sight polygons
    seen[:2] = route.exit_points(ends[:2], roadmap.sight)
    both = [roadmap.sight, disc_planes]
    v = len(static)
    n = len(ends) + v
    lengths = np.full((n, n), np.inf)
    lengths[: len(ends), : len(ends)] = _pair_lengths(ends, ends, both, seen, seen)
    if v:
        cross = _pair_lengths(ends, static, both, seen)
        lengths[: len(ends), len(ends):], lengths[len(ends):, : len(ends)] = cross, cross.T
        old = roadmap.node_edges[np.ix_(keep, keep)]
        lengths[len(ends):, len(ends):] = np.where(np.isfinite(old), _pair_lengths(static, static, [disc_planes]), np.inf)
    np.fill_diagonal(lengths, np.inf)
    return DetourGraph(np.vstack([ends, static]), lengths, discs, walls)


def shortest_first_step(graph: DetourGraph) -> tuple[np.ndarray | None, float]:
    """The first point after the estimate on the shortest path estimate → goal and the
    path length left after it (``(None, inf)`` when the goal cannot be reached)."""
    weights = np.where(np.isfinite(graph.lengths), np.maximum(graph.lengths, _EPS), 0.0)
    dist, pred = dijkstra(weights, directed=False, indices=0, return_predecessors=True)
    if not np.isfinite(dist[1]):
        return None, np.inf
    node = 1
    while pred[node] != 0:
        node = pred[node]
    return graph.points[node], float(dist[1] - dist[node])


def remembered_obstacles(estimates: np.ndarray, anchors: np.ndarray, still: np.ndarray, i: int, memory: np.ndarray,
                         goal: np.ndarray, local_box: float, radius: float) -> np.ndarray:
    """Robot ``i``'s still obstacles ``(M, 2)``, each at its ``anchor`` (the still test's
    running mean): the still neighbours anchored in its local box (those closer than
    ``radius`` to its goal left out: parked on it, they yield) and the ones it remembers
    from earlier steps that now lie outside its box (where it cannot see whether they
    moved); inside the box only what it sees now counts. The box test is on the anchors,
    the points kept, so a remembered anchor is dropped when the neighbour's anchor is back
    in the box, never kept beside it."""
    seen = still & np.all(np.abs(anchors - estimates[i]) <= local_box, axis=1)
    seen[i] = False
    seen &= np.linalg.norm(anchors - goal, axis=1) > radius
    out_of_sight = memory[np.any(np.abs(memory - estimates[i]) > local_box, axis=1)]
    return np.vstack([anchors[seen], out_of_sight])


def detour_subgoal(roadmap: route.Roadmap, estimate: np.ndarray, goal: np.ndarray, obstacles: np.ndarray,
                   radius: float, params: DetourParams) -> tuple[np.ndarray | None, float]:
    """The first point of the shortest path around the ``obstacles`` (discs of
    ``radius``) and the path length left after it; ``(None, inf)`` without a path."""
    if len(obstacles) == 0:
        return None, np.inf
    return shortest_first_step(detour_graph(roadmap, estimate, goal, obstacles, radius, params))


class Detours:
    """One team's detour rule (module docstring); every robot keeps only its own memory
    (its latch; the still counts are what each robot computes from the estimates it sees,
    identical for all robots that see the same estimates, so one tracker serves all)."""

    def __init__(self, roadmap: route.Roadmap, goals: np.ndarray, pair_clearance: float, local_box: float,
                 params: DetourParams = DetourParams(), stillness: YieldingParams = YieldingParams()):
        self.roadmap, self.goals, self.radius, self.local_box = roadmap, goals, pair_clearance, local_box
        self.rules, self.params = stillness, params
        self.tracker = StillTracker.initial(len(goals))
        self.left = np.zeros(len(goals), np.int32)
        self.active = np.zeros(len(goals), bool)
        self.memory = [np.zeros((0, 2)) for _ in goals]

    def apply(self, estimates: np.ndarray, arrived: np.ndarray, sub: np.ndarray, to_go: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """This step's sub-goals and path lengths with the detours of the blocked robots."""
        p, rules = self.params, self.rules
        counts = self.tracker.observe(estimates, rules.still_radius, rules.still_steps)
        still = counts >= rules.still_steps
        start = ~arrived & (counts >= p.block_steps) & (self.left <= 0) & self._sees_still(estimates, still)
        self.left[start] = p.steps
        self.left[arrived] = 0
        for i in np.flatnonzero(self.left <= 0):
            self.memory[i] = self.memory[i][:0]
        rows = np.flatnonzero(self.left > 0)
        self.left -= self.left > 0
        self.active[:] = False
        if len(rows) == 0:
            return sub, to_go
        sub, to_go = sub.copy(), to_go.copy()
        for i in rows:
            self.memory[i] = remembered_obstacles(estimates, self.tracker.mean, still, i, self.memory[i], self.goals[i],
                                                  self.local_box, self.radius)
            point, rest = detour_subgoal(self.roadmap, estimates[i], self.goals[i], self.memory[i], self.radius, p)
            if point is None:  # no still obstacle left (or no way round): back to the roadmap
                self.left[i], self.memory[i] = 0, self.memory[i][:0]
                continue
            sub[i], to_go[i], self.active[i] = point, np.linalg.norm(point - estimates[i]) + rest, True
        return sub, to_go

    def _sees_still(self, estimates: np.ndarray, still: np.ndarray) -> np.ndarray:
        """``(N,)``: some other robot in the local box holds still."""
        if not still.any():
            return np.zeros(len(estimates), bool)
        in_box = cKDTree(estimates[still]).query_ball_point(estimates, self.local_box, p=np.inf, return_length=True)
        return in_box - still > 0  # a still robot finds itself in its own box
