"""Revised prioritized planning (RPP; Čáp, Novák, Kleiner & Selecký 2015), the planner that
produces the label-flipping deadlock paper (2021)'s initial trajectories.

Robots plan one after another in priority order (robot index). Robot ``i`` runs a
space-time A* on a roadmap (a grid of spacing ``grid_spacing`` inside the free space
eroded by ``r``, nodes joined within ``connection_radius``), with

* moves along roadmap edges at constant maximum speed and waits of ``wait_steps``
  simulation steps (waiting at the goal is free: the search ends there);
* the discs of radius ``2r`` around the *starts* of all lower-priority robots as static
  obstacles (what makes RPP complete on valid infrastructures);
* the trajectories of all higher-priority robots as moving discs, each parked at its
  goal once it has arrived — so a robot may only stop at its goal after the last
  moment a higher-priority robot passes there;
* the heuristic "shortest roadmap travel time to the goal" (Dijkstra, admissible).

Time is the simulation step Δ, so a plan is directly the sampled trajectory ``π_i``.
(The authors' release planned with 540 ms steps; here a wait lasts ``wait_steps`` Δ.)

Valid infrastructure (Čáp et al.): every robot has a start-to-goal roadmap path avoiding
the ``2r`` discs around all other robots' starts and goals. :func:`check_valid_infrastructure`
tests it; RPP is guaranteed to succeed on such instances.
"""

from __future__ import annotations

import functools
import heapq
from dataclasses import dataclass

import numba
import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ..core.errors import InfeasibleError
from ..core.geometry import point_segment_distance
from ..core.workspace import Workspace
from .endpoints import check_endpoints
from .trajectories import Trajectories, make_trajectories


@dataclass(frozen=True)
class PlannerSettings:
    """Parameters of the roadmap and the space-time search (lengths in map units)."""

    radius: float
    speed: float
    dt: float
    grid_spacing: float = 75.0
    connection_radius: float = 120.0
    wait_steps: int = 5
    max_steps: int = 20000
    max_expansions: int = 400000


@dataclass(frozen=True)
class Roadmap:
    """Roadmap nodes ``(N, 2)`` and undirected edges ``(E, 2)`` (both directions listed)."""

    nodes: np.ndarray
    edges: np.ndarray

    @functools.cached_property
    def lengths(self) -> np.ndarray:
        return np.linalg.norm(self.nodes[self.edges[:, 1]] - self.nodes[self.edges[:, 0]], axis=1)

    def distances_to_edges(self, points: np.ndarray) -> np.ndarray:
        """``(P, E)``: distance from each point to each edge's segment."""
        a, b = self.nodes[self.edges[:, 0]], self.nodes[self.edges[:, 1]]
        return point_segment_distance(np.asarray(points, dtype=float).reshape(-1, 2), a, b)


def build_roadmap(workspace: Workspace, settings: PlannerSettings, extra_points: np.ndarray) -> Roadmap:
    """Grid nodes inside the free space eroded by ``r`` plus ``extra_points`` (starts, goals),
    joined when closer than ``connection_radius`` and the segment stays in the eroded space."""
    eroded = shapely.buffer(workspace.free_polygon, -settings.radius)
    shapely.prepare(eroded)
    xmin, ymin, xmax, ymax = workspace.extent
    s = settings.grid_spacing
    gx, gy = np.meshgrid(np.arange(xmin + s / 2, xmax, s), np.arange(ymin + s / 2, ymax, s))
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    grid = grid[shapely.contains_xy(eroded, grid[:, 0], grid[:, 1])]
    nodes = np.concatenate([grid, np.asarray(extra_points, dtype=float).reshape(-1, 2)])
    pairs = cKDTree(nodes).query_pairs(settings.connection_radius, output_type="ndarray")
    lines = shapely.linestrings(np.stack([nodes[pairs[:, 0]], nodes[pairs[:, 1]]], axis=1))
    pairs = pairs[shapely.contains(eroded, lines) | shapely.covers(eroded, lines)]
    return Roadmap(nodes, np.concatenate([pairs, pairs[:, ::-1]]))


def check_valid_infrastructure(roadmap: Roadmap, starts: np.ndarray, goals: np.ndarray, radius: float,
                               start_nodes: np.ndarray, goal_nodes: np.ndarray, endpoint_distances: np.ndarray | None = None) -> None:
    """Raise unless every robot reaches its goal avoiding the ``2r`` discs of all other endpoints.

    ``endpoint_distances``: ``roadmap.distances_to_edges`` of the starts followed by the
    goals ``(2n, E)``, computed here when not given (one distance per endpoint and edge,
    shared by all robots' tests).

    Raises
    ------
    InfeasibleError
        Naming the first robot without such a path.
    """
    n = len(starts)
    if endpoint_distances is None:
        endpoint_distances = roadmap.distances_to_edges(np.concatenate([starts, goals]))
    clear = clear_of_other_endpoints(endpoint_distances, n, 2 * radius)
    for i in range(n):
        ok_edges = clear[i]
        if not np.isfinite(_distances(roadmap, ok_edges, int(goal_nodes[i]))[start_nodes[i]]):
            raise InfeasibleError(
                f"robots[{i}]: expected a valid infrastructure (a path from start {starts[i].round(1).tolist()} to goal "
                f"{goals[i].round(1).tolist()} avoiding the other robots' starts and goals), received none"
            )


def clear_of_other_endpoints(endpoint_distances: np.ndarray, n: int, reach: float) -> np.ndarray:
    """``(n, E)``: the edges whose segment keeps distance ``≥ reach`` from every start and
    goal but robot ``i``'s own (``endpoint_distances`` ``(2n, E)``, starts then goals) —
    :func:`_clear_of` of the other rows, for all robots in ``O(n E)``."""
    near = endpoint_distances < reach
    return (near.sum(axis=0)[None, :] - near[:n] - near[n:]) == 0


def clear_of_later_starts(endpoint_distances: np.ndarray, n: int, reach: float) -> np.ndarray:
    """``(n, E)``: the edges whose segment keeps distance ``≥ reach`` from the starts of
    robots ``i + 1 … n − 1`` (the lower-priority robots of robot ``i``) — :func:`_clear_of`
    of those rows, for all robots in ``O(n E)``."""
    near = endpoint_distances[:n] < reach
    later = np.zeros_like(near)
    later[:-1] = np.logical_or.accumulate(near[::-1], axis=0)[::-1][1:]
    return ~later


def _clear_of(distances: np.ndarray, n_edges: int, reach: float) -> np.ndarray:
    """Edges ``(E,)`` whose segment keeps distance ``≥ reach`` from every point (``distances`` ``(P, E)``)."""
    if len(distances) == 0:
        return np.ones(n_edges, dtype=bool)
    return distances.min(axis=0) >= reach


def _distances(roadmap: Roadmap, edge_ok: np.ndarray, target: int, weights: np.ndarray | None = None) -> np.ndarray:
    """Shortest-path lengths to ``target`` over the allowed edges (``inf`` when unreachable)."""
    e = roadmap.edges[edge_ok]
    w = (roadmap.lengths if weights is None else weights)[edge_ok]
    n = len(roadmap.nodes)
    graph = coo_matrix((w + 1e-9, (e[:, 1], e[:, 0])), shape=(n, n)).tocsr()
    return dijkstra(graph, directed=True, indices=target)


def plan_prioritized(workspace: Workspace, starts: np.ndarray, goals: np.ndarray, settings: PlannerSettings,
                     check_infrastructure: bool = True) -> Trajectories:
    """Plan collision-free trajectories for all robots (RPP).

    Raises
    ------
    ScenarioError
        A start or goal outside the free space (closer than ``r`` to a wall) or overlapping another.
    InfeasibleError
        No valid infrastructure, or a robot's space-time search fails within ``max_steps``.
    """
    starts, goals = np.asarray(starts, dtype=float), np.asarray(goals, dtype=float)
    check_endpoints(workspace, starts, goals, settings.radius)
    n = len(starts)
    roadmap = build_roadmap(workspace, settings, np.concatenate([starts, goals]))
    base = len(roadmap.nodes) - 2 * n
    start_nodes, goal_nodes = base + np.arange(n), base + n + np.arange(n)
    for i, node in enumerate(np.concatenate([start_nodes, goal_nodes])):
        if not np.any(roadmap.edges[:, 0] == node):
            which, k = ("starts", i) if i < n else ("goals", i - n)
            raise InfeasibleError(f"robots.{which}[{k}]: expected a point connected to the roadmap, received an isolated one")
    endpoint_distances = roadmap.distances_to_edges(np.concatenate([starts, goals]))
    if check_infrastructure:
        check_valid_infrastructure(roadmap, starts, goals, settings.radius, start_nodes, goal_nodes, endpoint_distances)
    paths: list[np.ndarray] = []
    clear = clear_of_later_starts(endpoint_distances, n, 2 * settings.radius)
    for i in range(n):
        edge_ok = clear[i]
        search = SpaceTimeSearch(roadmap, settings, start_nodes[i], goal_nodes[i], np.asarray(paths_to_array(paths)), edge_ok)
        path = search.run()
        if path is None:
            raise InfeasibleError(f"robots[{i}]: expected a trajectory to goal {goals[i].round(1).tolist()}, received none within {settings.max_steps} steps")
        paths.append(path)
    return make_trajectories(paths, settings.radius, settings.dt)


def paths_to_array(paths: list[np.ndarray]) -> np.ndarray:
    """Higher-priority plans as ``(T, m, 2)``, each padded with its goal."""
    if not paths:
        return np.empty((1, 0, 2))
    t = max(len(p) for p in paths)
    return np.stack([np.vstack([p, np.repeat(p[-1:], t - len(p), axis=0)]) for p in paths], axis=1)


class SpaceTimeSearch:
    """Space-time A* for one robot against moving (higher-priority) and static (lower-priority start) discs.

    States are ``(node, t)`` with ``t`` in simulation steps; an edge of length ``ℓ`` takes
    ``ceil(ℓ / (v Δ))`` steps, a wait ``wait_steps``. A move is collision-checked at every
    intermediate step against the higher-priority positions (compiled, :func:`space_time_astar`).
    ``higher`` ``(T, m, 2)``: the higher-priority plans padded with their goals; ``edge_ok``
    ``(E,)``: the roadmap edges clear of the lower-priority robots' start discs.
    """

    def __init__(self, roadmap: Roadmap, settings: PlannerSettings, start: int, goal: int, higher: np.ndarray, edge_ok: np.ndarray):
        self.roadmap, self.s = roadmap, settings
        self.start, self.goal = int(start), int(goal)
        self.higher = higher  # (T, m, 2)
        self.boxes = window_boxes(higher, PRUNE_WINDOW)
        self.reach2 = (2 * settings.radius) ** 2
        step_len = settings.speed * settings.dt
        self.duration = np.maximum(1, np.ceil(roadmap.lengths / step_len - 1e-9)).astype(int)
        self.h = _distances(roadmap, edge_ok, self.goal, self.duration.astype(float))
        if not np.isfinite(self.h[self.start]):
            raise InfeasibleError(f"roadmap node {self.start}: expected a path to the goal avoiding lower-priority starts, received none")
        order = np.argsort(roadmap.edges[:, 0], kind="stable")
        ok = order[edge_ok[order]]
        self.adj_ptr = np.searchsorted(roadmap.edges[ok, 0], np.arange(len(roadmap.nodes) + 1)).astype(np.int64)
        self.adj_to = roadmap.edges[ok, 1].astype(np.int64)
        self.adj_dur = self.duration[ok].astype(np.int64)
        self.goal_free_from = self._goal_free_from()

    def _goal_free_from(self) -> int:
        """First step from which no higher-priority robot comes within ``2r`` of the goal."""
        if self.higher.shape[1] == 0:
            return 0
        g = self.roadmap.nodes[self.goal]
        close = (((self.higher - g) ** 2).sum(-1) < self.reach2).any(axis=1)
        if close[-1]:
            return np.iinfo(np.int64).max  # a higher-priority robot is parked there
        hits = np.flatnonzero(close)
        return int(hits[-1]) + 1 if len(hits) else 0

    def run(self) -> np.ndarray | None:
        """The trajectory ``(K + 1, 2)``, or ``None`` if none is found within the limits."""
        chain = space_time_astar(
            self.roadmap.nodes, self.adj_ptr, self.adj_to, self.adj_dur, self.h, np.ascontiguousarray(self.higher, dtype=float),
            self.boxes, PRUNE_WINDOW, self.reach2, self.start, self.goal, self.goal_free_from, self.s.wait_steps, self.s.max_steps,
            self.s.max_expansions,
        )
        if len(chain) == 0:
            return None
        return self._trajectory(chain)

    def _trajectory(self, chain: np.ndarray) -> np.ndarray:
        """Sample the chain of states ``(node, t)`` ``(S, 2)`` at every step (straight moves at constant speed)."""
        chain = chain.tolist()
        nodes = self.roadmap.nodes
        out = [nodes[chain[0][0]][None]]
        for (u, t0), (v, t1) in zip(chain[:-1], chain[1:]):
            frac = np.arange(1, t1 - t0 + 1)[:, None] / (t1 - t0)
            out.append(nodes[u] + (nodes[v] - nodes[u]) * frac)
        return np.concatenate(out)


PRUNE_WINDOW = 16
"""Steps per window of the higher-priority robots' bounding boxes (:func:`window_boxes`)."""


def window_boxes(higher: np.ndarray, window: int) -> np.ndarray:
    """Bounding boxes ``(n_windows, m, 4)`` (xmin, ymin, xmax, ymax) of each higher-priority
    robot over each window of ``window`` steps of ``higher`` ``(T, m, 2)``."""
    t, m, _ = higher.shape
    n_windows = -(-t // window)
    padded = np.concatenate([higher, np.repeat(higher[-1:], n_windows * window - t, axis=0)]).reshape(n_windows, window, m, 2)
    return np.ascontiguousarray(np.concatenate([padded.min(axis=1), padded.max(axis=1)], axis=-1))


@numba.njit(cache=True)
def _move_clear(higher, boxes, window, reach2, ax, ay, bx, by, t0, d):
    """Does the straight move ``a → b`` over steps ``t0 + 1 … t0 + d`` keep ``≥ 2r`` from every
    higher-priority robot (position at step ``k`` clamped to the last planned step)?

    Point ``k`` of the move is ``a + (b − a)·(k / d)``, the sample the trajectory records.
    A robot whose bounding boxes over the move's windows of ``window`` steps
    (:func:`window_boxes`) lie at least ``2r`` (plus a rounding margin) from the move's
    bounding box along some axis cannot come within ``2r`` of any sample, so its samples
    are not compared: the answer is the one of comparing every sample. ``O(d m)`` at worst, ``O(m)`` box tests plus
    ``O(d)`` per nearby robot in practice.
    """
    last = higher.shape[0] - 1
    reach = np.sqrt(reach2) * (1.0 + 1e-9) + 1e-9
    x0, x1, y0, y1 = min(ax, bx), max(ax, bx), min(ay, by), max(ay, by)
    w0, w1 = min(t0 + 1, last) // window, min(t0 + d, last) // window
    for j in range(higher.shape[1]):
        near = False
        for w in range(w0, w1 + 1):
            if boxes[w, j, 0] - x1 < reach and x0 - boxes[w, j, 2] < reach and boxes[w, j, 1] - y1 < reach and y0 - boxes[w, j, 3] < reach:
                near = True
                break
        if not near:
            continue
        for k in range(1, d + 1):
            frac = k / d
            px, py = ax + (bx - ax) * frac, ay + (by - ay) * frac
            row = min(t0 + k, last)
            dx, dy = higher[row, j, 0] - px, higher[row, j, 1] - py
            if dx * dx + dy * dy < reach2:
                return False
    return True


@numba.njit(cache=True)
def _state_chain(parent, key, n_nodes):
    """States ``(node, t)`` ``(S, 2)`` from the start to ``key`` by following ``parent``."""
    keys = [key]
    while parent[key] >= 0:
        key = parent[key]
        keys.append(key)
    chain = np.empty((len(keys), 2), dtype=np.int64)
    for i in range(len(keys)):
        chain[len(keys) - 1 - i, 0] = keys[i] % n_nodes
        chain[len(keys) - 1 - i, 1] = keys[i] // n_nodes
    return chain


@numba.njit(cache=True)
def space_time_astar(nodes, adj_ptr, adj_to, adj_dur, h, higher, boxes, window, reach2, start, goal, goal_free_from, wait_steps,
                     max_steps, max_expansions):
    """Space-time A* of one robot (RPP, Čáp et al. 2015), compiled.

    States ``(node, t)`` are keyed ``t · N + node``; the open list is a binary heap of
    ``(t + h(node), t, node)`` (ties: earlier step, then lower node index); a state is
    generated once (its first parent is kept) and expanded once. Successors of ``(u, t)``:
    a wait of ``wait_steps`` at ``u``, then ``u``'s roadmap edges in their stored order,
    each kept if it ends by ``max_steps`` and :func:`_move_clear` accepts it. The search
    ends at the goal from step ``goal_free_from`` on, or after ``max_expansions``
    expansions. Returns the chain of states ``(S, 2)`` (node, step), empty when none is found.
    """
    n_nodes = nodes.shape[0]
    empty = np.empty((0, 2), dtype=np.int64)
    if higher.shape[1] > 0 and not _move_clear(higher, boxes, window, reach2, nodes[start, 0], nodes[start, 1], nodes[start, 0],
                                               nodes[start, 1], -1, 1):
        return empty
    heap = [(h[start], np.int64(0), np.int64(start))]
    parent = {np.int64(start): np.int64(-1)}
    closed = {np.int64(-1): True}
    expansions = 0
    while len(heap) > 0 and expansions < max_expansions:
        _, t, u = heapq.heappop(heap)
        key = t * n_nodes + u
        if key in closed:
            continue
        closed[key] = True
        expansions += 1
        if u == goal and t >= goal_free_from:
            return _state_chain(parent, key, n_nodes)
        for e in range(adj_ptr[u] - 1, adj_ptr[u + 1]):
            v, d = (u, wait_steps) if e < adj_ptr[u] else (adj_to[e], adj_dur[e])
            nxt = (t + d) * n_nodes + v
            if nxt in closed or nxt in parent or t + d > max_steps:
                continue
            if higher.shape[1] > 0 and not _move_clear(higher, boxes, window, reach2, nodes[u, 0], nodes[u, 1], nodes[v, 0], nodes[v, 1], t, d):
                continue
            parent[nxt] = key
            heapq.heappush(heap, (t + d + h[v], t + d, v))
    return empty
