"""Per-run results of a coordination run, written into ``trace.results`` (so every sweep
row carries them): the outcome (Definition 1's deadlock, finished, collisions), the flips
(the label-flipping deadlock paper (2021)'s Fig. 6 c), their decision time (Fig. 6 b), the travel times (Fig. 6 a)
and the metric every method is compared by, the unnecessary waiting: the travel time
above the *delay-only lower bound*, each robot executing its plan alone under its own
disturbances (:func:`delay_only_arrival_steps`); :func:`waiting_removed_share` compares
two methods by it.

Every key is documented in :data:`RESULTS` (the family's ``results`` table).
"""

from __future__ import annotations

import numba
import numpy as np

from .theory import TheoryReport
from .instance import Instance
from .plan_execution import DisturbanceStream, ExecutionState, Variant

RESULTS: dict[str, str] = {
    "variant": "the execution policy: RMTRACK, RMTRACK+TFF or RMTRACK+TFA ('(checked)' with the segment-graph deadlock check), BTPG or optimal",
    "finished": "every robot reached its goal",
    "deadlock": "the run ended in a deadlock (Definition 1: some robot waiting, none moving)",
    "collisions": "robot pairs that ever came closer than 2r (0 for every RMTRACK variant)",
    "collision_events": "(step, pair) contacts closer than 2r",
    "flips": "label flips made (Fig. 6 c)",
    "refused_flips": "flips a flip test wanted that the deadlock check refused (they would close a cycle); optimal: decisions cut back because a flip would close a cycle through an obstacle not yet decided",
    "flip_tests": "flip tests evaluated",
    "decision_seconds": "wall time of the flip tests and cycle checks of the run (Fig. 6 b), and of the optimal method's searches",
    "step_decision_seconds": "decision_seconds per executed step",
    "mean_travel_time": "mean arrival time over robots in seconds (Fig. 6 a; NaN unless finished)",
    "total_travel_time": "sum of the arrival times in seconds (NaN unless finished)",
    "makespan": "last arrival time in seconds (NaN unless finished)",
    "planned_mean_travel_time": "mean planned duration K_i Δ in seconds (the undisturbed plan)",
    "delay_only_total_travel_time": "sum of the arrival times (s) of the robots executing their plans alone, each under its own disturbances (the same draws): the delay-only lower bound (NaN if one would not arrive within the step budget)",
    "unnecessary_waiting": "total_travel_time minus delay_only_total_travel_time (s): the time lost to interactions (NaN unless finished)",
    "decisions": "decisions of the optimal method (periodic, or called by a robot stopped where the order may change)",
    "budget_exhausted": "decisions of the optimal method whose node budget ran out before optimality was proved",
    "offline_seconds": "wall time of BTPG's offline classification of the obstacles",
    "switchable": "obstacles BTPG classified switchable",
    "n_obstacles": "coordination-space obstacles of the plan",
    "non_conflicting": "the plan is non-conflicting (Definition 4)",
    "disjoint_segments": "the plan's collision segments are disjoint (Theorem 4)",
    "plan_id": "digest of the executed plan: runs with equal plan_id executed the same plan",
    "instance_attempt": "which draw of the instance seed was planned (0 = the first; later ones replace unplannable draws)",
    "plan_seconds": "wall time to plan (or read) the instance and build its coordination space, when first computed in the process",
}


def run_results(variant: Variant, state: ExecutionState, arrival_steps: np.ndarray, instance: Instance,
                report: TheoryReport, probability: np.ndarray, n_steps: int, max_steps: int) -> dict:
    """Every :data:`RESULTS` key of one run, from its final execution state.

    ``probability`` ``(n, K_max + 1)``: the true disturbance probability at each plan step;
    ``n_steps``: the steps executed; ``max_steps``: the step budget (also the delay-only runs')."""
    traj = instance.trajectories
    stats = state.stats
    finished = bool(np.all(arrival_steps >= 0))
    contacts = contact_metrics(state.events)
    travel = travel_metrics(arrival_steps, traj.lengths, traj.dt)
    alone = delay_only_arrival_steps(state.stream, probability, traj.lengths, max_steps)
    bound = float(alone.sum() * traj.dt) if np.all(alone >= 0) else float("nan")
    return {
        "success": finished and contacts["collision_events"] == 0,
        "variant": variant.name, "finished": finished, "deadlock": bool(state.deadlock), **contacts,
        "flips": int(stats["flips"]), "refused_flips": int(stats["refused"]), "flip_tests": int(stats["tests"]),
        "decision_seconds": float(stats["seconds"]),
        "step_decision_seconds": float(stats["seconds"] / max(n_steps, 1)),
        **travel,
        "delay_only_total_travel_time": bound, "unnecessary_waiting": travel["total_travel_time"] - bound,
        "decisions": int(stats["decisions"]), "budget_exhausted": int(stats["exhausted"]),
        "offline_seconds": float(stats["offline_seconds"]), "switchable": int(stats["switchable"]),
        "n_obstacles": instance.space.n_obstacles, "non_conflicting": bool(report.non_conflicting),
        "disjoint_segments": bool(report.disjoint_segments), "plan_id": instance.digest,
        "instance_attempt": int(instance.attempt), "plan_seconds": float(instance.seconds),
    }


def delay_only_arrival_steps(stream: DisturbanceStream, probability: np.ndarray, lengths: np.ndarray, max_steps: int) -> np.ndarray:
    """Arrival step of each robot executing its plan alone: at step ``t`` it advances unless
    disturbed (``u_i(t) < p(π_i(x_i))``, the run's own draws), with no robot to wait for;
    ``-1`` when it would not arrive within ``max_steps``.

    Waiting only adds steps and every draw is independent of the past, so in expectation no
    execution of the plan finishes a robot sooner: the sum is the *delay-only lower bound*
    (for one run's draws a robot that waited may meet fewer disturbances, so a run can
    beat it by a little). ``O(n T)``, compiled, ``T`` the last arrival.
    """
    n = len(lengths)
    x = np.zeros(n, dtype=np.intp)
    arrival = np.where(np.asarray(lengths) == 0, 0, -1).astype(np.intp)
    block, size = 0, None
    while np.any(arrival < 0):
        draws = stream.block(block)
        size = len(draws)
        if block * size >= max_steps:
            break
        _advance_alone(draws, block * size, max_steps, x, arrival, probability, np.asarray(lengths, dtype=np.intp))
        block += 1
    return arrival


@numba.njit(cache=True)
def _advance_alone(draws, first_step, max_steps, x, arrival, probability, lengths):
    """One block of :func:`delay_only_arrival_steps` (in place)."""
    for row in range(len(draws)):
        t = first_step + row
        if t >= max_steps:
            return
        for i in range(len(x)):
            if arrival[i] >= 0:
                continue
            if draws[row, i] >= probability[i, x[i]]:
                x[i] += 1
                if x[i] >= lengths[i]:
                    arrival[i] = t + 1


def waiting_removed_share(unnecessary_waiting: float, baseline_waiting: float) -> float:
    """Share of a baseline's unnecessary waiting (travel time above the delay-only lower
    bound, :data:`RESULTS`) that a method removes: ``1 − W / W_baseline`` (1: no waiting
    left; 0: as much as the baseline; negative: more). NaN when the baseline has none."""
    if not np.isfinite(baseline_waiting) or baseline_waiting <= 0 or not np.isfinite(unnecessary_waiting):
        return float("nan")
    share = 1.0 - unnecessary_waiting / baseline_waiting
    return 0.0 if abs(share) < 1e-12 else float(share)  # the baseline itself: sums in another order round apart


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
