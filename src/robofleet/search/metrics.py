"""Per-run results of a search (Yang 2017), written into ``trace.results``.

Every value is computed from the observer's records (true positions, true visits, the
true targets), never from what the robots believe. :data:`RESULTS` documents each key;
it is the family's ``results`` table (:mod:`~robofleet.search.family`), so every sweep row carries them.

``completed`` is the stop rules' verdict: every working robot stopped, by its own rule
(3)/(4) or by a stop broadcast (step 8) that ends its search — in situation 2 only one
whose map covers the receiver's vertex, so a robot trapped in a pocket cut off by
obstacles never ends the others' search (:func:`.loop_kernels.stop_received`).
Without failures, a completed situation-2 run has therefore visited every accessible
vertex reachable from the starts; a failed robot can seal vertices off (their runs
complete with ``visited_share`` below 1 and no success).

``success`` is the paper's goal met, and only then: the search ended by its stop rules
(``completed``) with every target found (situation 1, rule (3)), or with every accessible
vertex reachable from the starts visited and every listed target found (situation 2,
rule (4)), and no robot ever collided with another robot or touched an obstacle (a
collision-free search, Section 2). Vertices in parts of a disconnected grid that hold no
robot are not reachable from the starts; ``robofleet check`` reports such grids.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .coverage import CoverageProbe
from .grids import Grid

RESULTS: dict[str, str] = {
    "search_time": "simulated seconds until the last working robot stopped (or the step budget ran out): motion plus choice rounds plus collision penalties",
    "completed": "every working robot stopped by rule (3) (all targets known, situation 1) or (4) (no unvisited vertex in its map, situation 2), its own or a stop broadcast whose map covers its vertex",
    "found_targets": "targets detected (within r_st of a robot) by the end",
    "n_targets": "targets in the scenario",
    "visited_share": "share of the accessible vertices reachable from the starts that a robot stood on",
    "detected_share": "share of A_d within r_st of a visited vertex (Section 3's complete search; sampled on an a/12 lattice)",
    "grid_limit_share": "share of A_d within r_st of an accessible vertex reachable from the starts: the best any search on this grid can detect",
    "accessible_vertices": "grid vertices a robot can stand on (clearance r_safe from obstacles and the border)",
    "collisions": "robot pairs that picked one vertex or swapped along one edge (RU and LFP allow them)",
    "obstacle_collisions": "moves that touched an obstacle left unsensed (only with r_so below Assumption 2.4)",
    "mean_rounds": "mean number of sequential choice rounds per step (step 5)",
    "failed_robots": "robots that failed (stopped moving and answering) during the run",
}
"""The per-run result keys and their meaning (beyond the core summary keys)."""


@dataclass(frozen=True)
class RunRecord:
    """What the observer recorded about one run (the inputs of :func:`run_results`).

    Attributes
    ----------
    situation:
        1 (number of targets known) or 2.
    search_time:
        simulated seconds.
    completed:
        whether every working robot stopped by a stop rule (own or received).
    steps:
        steps taken (moves).
    found:
        ``(T,)`` bool, targets known by some robot of the run.
    visited:
        ``(V,)`` bool, vertices a robot stood on.
    reachable:
        ``(V,)`` bool, accessible vertices reachable from the starts.
    collisions, obstacle_collisions, rounds, failed_robots:
        counts over the run.
    """

    situation: int
    search_time: float
    completed: bool
    steps: int
    found: np.ndarray
    visited: np.ndarray
    reachable: np.ndarray
    collisions: int
    obstacle_collisions: int
    rounds: int
    failed_robots: int


def run_results(record: RunRecord, grid: Grid, r_st: float) -> dict:
    """The per-run results of :data:`RESULTS` plus ``success``, as plain scalars.

    Coverage shares use the cached :class:`~.coverage.CoverageProbe` of the grid (one
    sparse matrix–vector product each).
    """
    probe = coverage_probe(grid, r_st)
    found_targets = int(record.found.sum())
    visited_share = float(record.visited[record.reachable].mean()) if record.reachable.any() else 1.0
    results = {
        "search_time": float(record.search_time),
        "completed": bool(record.completed),
        "found_targets": found_targets,
        "n_targets": len(record.found),
        "visited_share": visited_share,
        "detected_share": probe.detected_share(record.visited),
        "grid_limit_share": probe.detected_share(record.reachable),
        "accessible_vertices": int(grid.accessible.sum()),
        "collisions": int(record.collisions),
        "obstacle_collisions": int(record.obstacle_collisions),
        "mean_rounds": float(record.rounds / max(record.steps, 1)),
        "failed_robots": int(record.failed_robots),
    }
    return {"success": is_success(record, found_targets, visited_share), **results}


def is_success(record: RunRecord, found_targets: int, visited_share: float) -> bool:
    """The search's goal met (see the module docstring): stopped by rule (3)/(4) with every
    target found — in situation 2 also every reachable accessible vertex visited — and no
    collision with a robot or an obstacle."""
    covered = record.situation == 1 or visited_share == 1.0
    collision_free = record.collisions == 0 and record.obstacle_collisions == 0
    return bool(record.completed and found_targets == len(record.found) and covered and collision_free)


@lru_cache(maxsize=32)
def coverage_probe(grid: Grid, r_st: float) -> CoverageProbe:
    """The coverage probe of a grid at target range ``r_st`` (built once per process)."""
    return CoverageProbe(grid, r_st)
