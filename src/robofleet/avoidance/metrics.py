"""Per-run results of an avoidance run, written into ``trace.results`` (so every sweep
row carries them), all judged on TRUE positions.

* the motion summary of :func:`robofleet.core.metrics.motion_summary` (success, contacts,
  clearances, arrivals, travel times), extended to the 3-D box obstacles of ``space3d``;
* the controllers' counts: deadlock detections (the heuristic of appendix C: firings of
  its stuck-robot test, not proven deadlocks), empty-cell robot-steps,
  MPC fallback robot-steps;
* the empirical collision frequencies the chance constraint speaks about: per robot pair
  and step (``pair_step_rate``, bounded by δ at every step when the premise holds), per
  pair over the run, per robot and step against obstacles, and per run.

Every key is documented in :data:`RESULTS` (and thereby in ``FAMILY.results``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..core import geometry, metrics
from ..core.workspace import Workspace

RESULTS: dict[str, str] = {
    "collisions": "distinct robot pairs that touched (centres closer than 2 r_s) at some step",
    "obstacle_collisions": "distinct robots that touched a static obstacle (2-D polygon or 3-D box)",
    "collision_steps": "contacts counted per step: (pair, step) plus (robot, step) obstacle contacts",
    "min_pair_distance": "smallest centre distance between two robots over the run [m]",
    "min_obstacle_distance": "smallest centre distance from a robot to an obstacle over the run [m]",
    "arrived": "share of robots home at the end: within goal_tolerance of their goal by their own estimate when they last held, not stepping aside or returning (simulations); robots that reached their goal (the environment, the ROS 2 node)",
    "max_true_goal_distance": "largest distance from a robot's TRUE final position to its goal [m] (robots stop on noisy estimates: up to about goal_tolerance + 3σ)",
    "makespan": "time until the last robot arrived [s] (null unless all arrived)",
    "mean_travel_time": "mean arrival time over the robots that arrived [s]",
    "median_step_seconds": "median compute time of one step for the whole team (cells + controllers) [s]",
    "deadlock_detections": "heuristic count: times the stuck-robot test of appendix C fired (too little progress towards the goal over a window, or the projected goal at the estimate), summed over robots; each firing starts a recovery, so a run that succeeds may count many, and a count is no proof of a deadlock",
    "livelock_detections": "heuristic count: of deadlock_detections, the single-integrator firings while the robot was moving (mean commanded speed ≥ v_max/2 over the window), classed as livelocks",
    "empty_cell_steps": "robot-steps whose cell was empty (the robot held still)",
    "mpc_fallback_steps": "robot-steps where the MPC found no in-cell plan and applied the least-violating plan (or braking) instead",
    "mpc_fallback_share": "MPC fallback robot-steps over the robot-steps an MPC solved for (robots not yet arrived); null without MPC",
    "pair_step_rate": "colliding (pair, step) couples over all couples, the frequency the chance constraint bounds by δ",
    "pair_rate": "share of robot pairs that collided at least once",
    "obstacle_step_rate": "colliding (robot, step) couples with obstacles over all couples",
    "run_collided": "whether any robot-robot or robot-obstacle contact happened in the run",
    "close_pair_steps": "(pair, step) couples whose centres were closer than CLOSE_PAIR_DISTANCE = 1 m (initial state included)",
    "close_pair_step_rate": "colliding (pair, step) couples among the close ones (centres under 1 m); null without close couples",
    "estimate_in_cell_share": "share of robot-steps, of robots not yet arrived (steps before the arrival step), whose estimate lay in the robot's own cell when it was built (the premise of the chance constraint); null for ORCA",
    "empty_cell_share": "share of robot-steps, of robots not yet arrived (steps before the arrival step), whose cell was empty; null for ORCA",
}

CLOSE_PAIR_DISTANCE = 1.0
"""Centre distance in metres under which two robots count as a close pair at a step: the
pair-steps where a collision is possible at all, so the rate among them is not diluted by
far-apart pairs."""


@dataclass(frozen=True)
class ControllerCounts:
    """What the controllers counted during a run."""

    deadlock_detections: int = 0
    livelock_detections: int = 0
    empty_cell_steps: int = 0
    mpc_fallback_steps: int = 0
    mpc_solve_steps: int = 0


def box_distance(points: np.ndarray, centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray) -> np.ndarray:
    """Euclidean distance ``(..., O)`` from points ``(..., 3)`` to boxes yawed about z (0 inside)."""
    rel = points[..., None, :] - centers
    c, s = np.cos(yaws), np.sin(yaws)
    local = np.stack([c * rel[..., 0] + s * rel[..., 1], -s * rel[..., 0] + c * rel[..., 1], rel[..., 2]], -1)
    return np.linalg.norm(np.maximum(np.abs(local) - 0.5 * sizes, 0.0), axis=-1)


def box_contacts(positions: np.ndarray, radius: float, boxes: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, float]:
    """Robot–box contacts ``(step, robot)`` (clearance ``< r_s − CONTACT_TOL``) over a run
    ``(T, N, 3)``, and the smallest centre–box distance (``inf`` without boxes)."""
    if boxes is None or len(boxes[0]) == 0:
        return np.empty((0, 2), dtype=np.intp), float("inf")
    centers, sizes, yaws = boxes
    nearest = box_distance(positions, centers, sizes, yaws).min(axis=2)
    return np.argwhere(nearest < radius - metrics.CONTACT_TOL).astype(np.intp), float(nearest.min())


def collision_frequencies(n_robots: int, n_frames: int, pair_contacts: int, colliding_pairs: int, obstacle_contacts: int) -> dict:
    """Empirical collision frequencies of one run.

    Parameters
    ----------
    n_robots, n_frames:
        Team size and recorded states (steps + 1, the initial state included).
    pair_contacts:
        Colliding (pair, step) couples; ``colliding_pairs`` the distinct pairs among them.
    obstacle_contacts:
        Colliding (robot, step) couples with obstacles.

    Returns
    -------
    dict
        ``pair_step_rate`` (over ``N(N−1)/2 · frames`` couples: the per-step pair
        probability the chance constraint bounds by δ), ``pair_rate``,
        ``obstacle_step_rate`` (over ``N · frames``) and ``run_collided``.
    """
    pairs = n_robots * (n_robots - 1) / 2
    return {
        "pair_step_rate": pair_contacts / (pairs * n_frames) if pairs else 0.0,
        "pair_rate": colliding_pairs / pairs if pairs else 0.0,
        "obstacle_step_rate": obstacle_contacts / (n_robots * n_frames),
        "run_collided": bool(pair_contacts or obstacle_contacts),
    }


def close_pair_frequencies(positions: np.ndarray, radius: float, distance: float = CLOSE_PAIR_DISTANCE) -> dict:
    """Contacts among close (pair, step) couples (centres under ``distance``) over a run ``(T, N, d)``.

    The pooled ``pair_step_rate`` divides by all ``N(N−1)/2`` pairs, most of them far apart;
    the rate among close couples compares methods where the chance constraint binds.
    """
    close = contacts = 0
    for pts in positions:
        close_here, contacts_here = close_pair_counts(pts, radius, distance)
        close += close_here
        contacts += contacts_here
    return close_pair_rate(close, contacts)


def close_pair_counts(points: np.ndarray, radius: float, distance: float = CLOSE_PAIR_DISTANCE) -> tuple[int, int]:
    """Close pairs (centres under ``distance``) of one state ``(N, d)`` and the contacts among them."""
    pairs = geometry.close_pairs(points, distance)
    if len(pairs) == 0:
        return 0, 0
    gaps = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)
    return len(pairs), int(np.count_nonzero(gaps < 2 * radius - metrics.CONTACT_TOL))


def close_pair_rate(close: int, contacts: int) -> dict:
    """``close_pair_steps`` and ``close_pair_step_rate`` from the counts over a run."""
    return {"close_pair_steps": int(close), "close_pair_step_rate": contacts / close if close else float("nan")}


def premise_shares(estimate_in_cell: np.ndarray, empty_cell: np.ndarray, arrivals: np.ndarray) -> dict:
    """Shares of the robot-steps ``(k, i)`` of robots not yet arrived (``k`` below the
    arrival step, or every step for a robot that never arrived) whose estimate lay in its
    cell, and whose cell was empty (``nan`` without such robot-steps)."""
    steps = np.arange(len(estimate_in_cell))[:, None]
    moving = (arrivals[None, :] < 0) | (steps < arrivals[None, :])
    count = int(moving.sum())
    if count == 0:
        return {"estimate_in_cell_share": float("nan"), "empty_cell_share": float("nan")}
    return {"estimate_in_cell_share": float(estimate_in_cell[moving].mean()), "empty_cell_share": float(empty_cell[moving].mean())}


class RunTally:
    """The raw counts behind :data:`RESULTS`, gathered state by state (:meth:`add_state`)
    and step by step (:meth:`add_step`) as a run goes, so that a run keeping only every
    k-th state (``record_every``) is judged on every state all the same; the per-state
    functions are those :func:`run_results` applies to a whole recorded run.

    Parameters
    ----------
    radius:
        Robot radius r_s.
    workspace:
        The 2-D workspace (its polygon obstacles), ``None`` in 3-D.
    boxes:
        The 3-D box obstacles (centres, sizes, yaws), ``None`` in 2-D.
    """

    def __init__(self, radius: float, workspace: Workspace | None, boxes: tuple[np.ndarray, np.ndarray, np.ndarray] | None):
        self.radius, self.workspace, self.boxes = radius, workspace, boxes
        self.pair_rows: list[np.ndarray] = []
        self.pair_min: list[float] = []
        self.obstacle_rows: list[np.ndarray] = []
        self.obstacle_min: list[float] = []
        self.close = self.close_contacts = 0
        self.robot_steps = self.in_cell = self.empty = 0
        self.seconds = 0.0

    @property
    def states(self) -> int:
        """States tallied so far (steps + 1)."""
        return len(self.pair_min)

    def add_state(self, row: int, positions: np.ndarray) -> None:
        """Tally the contacts and distances of the TRUE positions ``(N, d)`` after ``row`` steps."""
        t0 = time.perf_counter()
        state = np.asarray(positions, float)[None]
        contacts, nearest = metrics.pair_contacts(state, self.radius)
        self.pair_rows.append(at_step(contacts, row))
        self.pair_min.append(float(nearest[0]))
        if self.workspace is not None:
            hits, distance = metrics.obstacle_contacts(state, self.radius, self.workspace)
            self.obstacle_min.append(float(distance.min(initial=np.inf)))
        else:
            hits, distance = box_contacts(state, self.radius, self.boxes)
            self.obstacle_min.append(distance)
        self.obstacle_rows.append(at_step(hits, row))
        close, close_contacts = close_pair_counts(state[0], self.radius)
        self.close += close
        self.close_contacts += close_contacts
        self.seconds += time.perf_counter() - t0

    def add_step(self, estimate_in_cell: np.ndarray, empty_cell: np.ndarray, moving: np.ndarray) -> None:
        """Tally one step's premise flags over the robots still ``moving`` (not yet arrived)."""
        self.robot_steps += int(np.count_nonzero(moving))
        self.in_cell += int(np.count_nonzero(estimate_in_cell & moving))
        self.empty += int(np.count_nonzero(empty_cell & moving))

    def premise_shares(self) -> dict:
        """:func:`premise_shares` from the tallied counts."""
        if self.robot_steps == 0:
            return {"estimate_in_cell_share": float("nan"), "empty_cell_share": float("nan")}
        return {"estimate_in_cell_share": self.in_cell / self.robot_steps, "empty_cell_share": self.empty / self.robot_steps}

    def results(self, *, dt: float, step_seconds: np.ndarray, arrivals: np.ndarray, counts: ControllerCounts, premise: bool) -> dict:
        """Every per-run result of :data:`RESULTS` plus ``success`` (see :func:`run_results`);
        ``premise`` False (a method without cells) gives ``nan`` shares."""
        contacts, hits = np.concatenate(self.pair_rows), np.concatenate(self.obstacle_rows)
        in_plane = self.workspace is not None
        out = metrics.contact_summary(contacts, np.array(self.pair_min), hits if in_plane else np.empty((0, 2), np.intp),
                                      np.array(self.obstacle_min) if in_plane else np.full(self.states, np.inf),
                                      arrivals, dt, step_seconds, self.states - 1)
        for core_key in ("n_steps", "n_robots"):
            out.pop(core_key)
        obstacle_hits = len(hits)
        pair_contacts = out["collision_steps"] - obstacle_hits if in_plane else out["collision_steps"]
        if not in_plane:
            out["obstacle_collisions"] = int(len(np.unique(hits[:, 1])))
            out["min_obstacle_distance"] = float(min(self.obstacle_min, default=np.inf))
            out["collision_steps"] = int(pair_contacts + obstacle_hits)
            out["success"] = bool(out["success"] and obstacle_hits == 0)
        out.update(deadlock_detections=counts.deadlock_detections, livelock_detections=counts.livelock_detections,
                   empty_cell_steps=counts.empty_cell_steps, mpc_fallback_steps=counts.mpc_fallback_steps,
                   mpc_fallback_share=counts.mpc_fallback_steps / counts.mpc_solve_steps if counts.mpc_solve_steps else None)
        out.update(collision_frequencies(len(arrivals), self.states, pair_contacts, out["collisions"], obstacle_hits))
        out.update(close_pair_rate(self.close, self.close_contacts))
        out.update(self.premise_shares() if premise else {"estimate_in_cell_share": float("nan"), "empty_cell_share": float("nan")})
        return out


def at_step(rows: np.ndarray, step: int) -> np.ndarray:
    """Contact rows ``(step, ...)`` of a one-state run, stamped with the run's ``step``."""
    rows = np.array(rows, np.intp)
    rows[:, 0] = step
    return rows


def run_results(
    positions: np.ndarray,
    goals: np.ndarray,
    *,
    radius: float,
    dt: float,
    goal_tolerance: float,
    workspace: Workspace | None,
    boxes: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
    step_seconds: np.ndarray,
    arrivals: np.ndarray,
    counts: ControllerCounts,
    premise: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict:
    """Every per-run result of :data:`RESULTS` plus ``success``.

    Parameters
    ----------
    positions:
        True positions ``(T + 1, N, d)``.
    goals:
        ``(N, d)``.
    workspace:
        The 2-D workspace (its obstacles are the polygon obstacles), ``None`` in 3-D.
    boxes:
        The 3-D box obstacles (centres, sizes, yaws), ``None`` in 2-D.
    arrivals:
        Per-robot arrival steps decided by the controllers (``-1`` = never).
    counts:
        The controllers' counters.
    premise:
        The recorded ``estimate_in_cell`` and ``empty_cell`` ``(T, N)`` arrays, ``None``
        for a method without cells (the shares are then ``nan``).

    Notes
    -----
    ``success`` is: every robot arrived and nothing touched (robots or obstacles). The
    whole run is tallied as :class:`RunTally` tallies a run step by step.
    """
    tally = RunTally(radius, workspace, boxes)
    for row, state in enumerate(positions):
        tally.add_state(row, state)
    if premise is not None:
        for k, (inside, empty) in enumerate(zip(*premise)):
            tally.add_step(inside, empty, (arrivals < 0) | (k < arrivals))
    return tally.results(dt=dt, step_seconds=step_seconds, arrivals=arrivals, counts=counts, premise=premise is not None)
