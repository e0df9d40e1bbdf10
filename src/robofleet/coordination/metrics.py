"""Per-run results of a coordination run, written into ``trace.results`` (so every sweep
row carries them): the outcome (Definition 1's deadlock, finished, collisions), the flips
(the label-flipping deadlock paper (2021)'s Fig. 6 c), their decision time (Fig. 6 b) and the travel times (Fig. 6 a).

Every key is documented in :data:`RESULTS` (the family's ``results`` table).
"""

from __future__ import annotations

import numpy as np

from .theory import TheoryReport
from .instance import Instance
from .plan_execution import ExecutionState, Variant

RESULTS: dict[str, str] = {
    "variant": "the execution policy: RMTRACK, RMTRACK+TFF or RMTRACK+TFA, '(checked)' with the segment-graph deadlock check",
    "finished": "every robot reached its goal",
    "deadlock": "the run ended in a deadlock (Definition 1: some robot waiting, none moving)",
    "collisions": "robot pairs that ever came closer than 2r (0 for every RMTRACK variant)",
    "collision_events": "(step, pair) contacts closer than 2r",
    "flips": "label flips made (Fig. 6 c)",
    "refused_flips": "flips a flip test wanted that the deadlock check refused (they would close a cycle)",
    "flip_tests": "flip tests evaluated",
    "decision_seconds": "wall time of the flip tests and cycle checks of the run (Fig. 6 b)",
    "mean_travel_time": "mean arrival time over robots in seconds (Fig. 6 a; NaN unless finished)",
    "total_travel_time": "sum of the arrival times in seconds (NaN unless finished)",
    "makespan": "last arrival time in seconds (NaN unless finished)",
    "planned_mean_travel_time": "mean planned duration K_i Δ in seconds (the undisturbed plan)",
    "n_obstacles": "coordination-space obstacles of the plan",
    "non_conflicting": "the plan is non-conflicting (Definition 4)",
    "disjoint_segments": "the plan's collision segments are disjoint (Theorem 4)",
    "plan_id": "digest of the executed plan: runs with equal plan_id executed the same plan",
    "instance_attempt": "which draw of the instance seed was planned (0 = the first; later ones replace unplannable draws)",
    "plan_seconds": "wall time to plan (or read) the instance and build its coordination space, when first computed in the process",
}


def run_results(variant: Variant, state: ExecutionState, arrival_steps: np.ndarray, instance: Instance,
                report: TheoryReport) -> dict:
    """Every :data:`RESULTS` key of one run, from its final execution state."""
    traj = instance.trajectories
    stats = state.stats
    finished = bool(np.all(arrival_steps >= 0))
    contacts = contact_metrics(state.events)
    return {
        "success": finished and contacts["collision_events"] == 0,
        "variant": variant.name, "finished": finished, "deadlock": bool(state.deadlock), **contacts,
        "flips": int(stats["flips"]), "refused_flips": int(stats["refused"]), "flip_tests": int(stats["tests"]),
        "decision_seconds": float(stats["seconds"]),
        **travel_metrics(arrival_steps, traj.lengths, traj.dt),
        "n_obstacles": instance.space.n_obstacles, "non_conflicting": bool(report.non_conflicting),
        "disjoint_segments": bool(report.disjoint_segments), "plan_id": instance.digest,
        "instance_attempt": int(instance.attempt), "plan_seconds": float(instance.seconds),
    }


def contact_metrics(events: list[dict]) -> dict:
    """``collisions`` (distinct robot pairs) and ``collision_events`` from the ``collision`` events."""
    pairs = [tuple(e["robots"]) for e in events if e["kind"] == "collision"]
    return {"collisions": len(set(pairs)), "collision_events": len(pairs)}


def travel_metrics(arrival_steps: np.ndarray, lengths: np.ndarray, dt: float) -> dict:
    """Travel times in seconds (``nan`` when a robot never arrived) and the planned mean."""
    arrived = arrival_steps >= 0
    times = np.where(arrived, arrival_steps * dt, np.nan)
    ok = bool(arrived.all())
    return {
        "mean_travel_time": float(np.mean(times)) if ok else float("nan"),
        "total_travel_time": float(np.sum(times)) if ok else float("nan"),
        "makespan": float(np.max(times)) if ok else float("nan"),
        "planned_mean_travel_time": float(np.mean(lengths) * dt),
    }
