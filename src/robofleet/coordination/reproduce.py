"""Reproduction of paper 000's Fig. 6 on the X-plus-corridor map.

For each robot count (5, 10, 15, 20) and each random instance (starts and goals drawn in
the flows' boxes, trajectories from the prioritized planner), the six variants — RMTRACK,
RMTRACK+TFF, RMTRACK+TFA, each with and without the segment-graph deadlock check — run
on the *same plan* and the *same disturbances* (one task = one instance = six rows).
Tasks go through :func:`robofleet.experiments.run_tasks` (processes by default, Dask
optional) into a resumable Parquet store.

Aggregates (Fig. 6 a–d): average travel time per robot (over instances where all six
variants finished, as the authors' release did), flip-decision time, number of flips,
share of instances finished without deadlock.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from ..core.errors import InfeasibleError
from ..core.rng import spawn_seeds
from ..scenarios.registry import load_scenario
from .coordination_space import build_coordination_space
from .scenario import build_plan, build_workspace, execution_trace, make_executor, travel_metrics
from .segment_graph import build_segment_layout
from .simulation import ALL_VARIANTS, Variant
from .theory import check_theory

ROBOT_COUNTS = (5, 10, 15, 20)
INSTANCE_ATTEMPTS = 5


def instance_mapping(task: dict, attempt: int = 0) -> dict:
    """The scenario mapping of one task (instance seed shifted on a retry)."""
    return {
        "family": "coordination",
        "workspace": {"preset": "x_corridor"},
        "disturbance": {"base_probability": task.get("base_probability", 0.05), "region_probability": task.get("region_probability", 0.85)},
        "robots": {"count": int(task["n_robots"]), "radius": 15.0, "speed": 50.0, "placement": "flows",
                   "instance_seed": int(task["instance_seed"]) + attempt * 1_000_003},
        "simulation": {"dt": 0.1, "max_steps": int(task.get("max_steps", 30000))},
    }


def plan_instance(task: dict):
    """Spec, workspace and plan of a task; retries another instance if planning fails."""
    for attempt in range(INSTANCE_ATTEMPTS):
        spec = load_scenario(instance_mapping(task, attempt))
        workspace = build_workspace(spec)
        try:
            return spec, workspace, build_plan(spec, workspace), attempt
        except InfeasibleError:
            continue
    raise InfeasibleError(f"task {task['run_id']}: expected a plannable instance, received {INSTANCE_ATTEMPTS} failures")


def run_instance(task: dict) -> list[dict]:
    """Task function: one instance, six variants, same plan and disturbances → six rows."""
    t0 = time.perf_counter()
    spec, workspace, traj, attempt = plan_instance(task)
    plan_seconds = time.perf_counter() - t0
    t0 = time.perf_counter()
    space = build_coordination_space(traj)
    space_seconds = time.perf_counter() - t0
    layout = build_segment_layout(space)
    theory = check_theory(traj, space)
    rows = []
    for variant in ALL_VARIANTS:
        ex = make_executor(traj, space, workspace, variant, spec.disturbance.base_probability, layout=layout)
        t0 = time.perf_counter()
        run = ex.run(int(task["seed"]), spec.simulation.max_steps)
        rows.append({
            "variant": variant.name, "method": variant.method.value, "deadlock_check": variant.deadlock_check,
            "deadlock": run.deadlock, "finished": run.finished, "collisions": run.collisions,
            "flips": run.flips, "refused_flips": run.refused_flips, "flip_tests": run.flip_tests,
            "decision_seconds": run.decision_seconds,
            "decision_ms_per_test": 1e3 * run.decision_seconds / run.flip_tests if run.flip_tests else float("nan"),
            "steps": run.n_steps, "run_seconds": time.perf_counter() - t0,
            "plan_seconds": plan_seconds, "space_seconds": space_seconds, "n_obstacles": space.n_obstacles,
            "non_conflicting": theory.non_conflicting, "disjoint_segments": theory.disjoint_segments,
            "instance_attempt": attempt, **travel_metrics(traj, run),
        })
    return rows


def make_tasks(robot_counts: Sequence[int] = ROBOT_COUNTS, instances: int = 10, root_seed: int = 0,
               base_probability: float = 0.05, region_probability: float = 0.85, max_steps: int = 30000) -> list[dict]:
    """One task per (robot count, instance) with its own instance and disturbance seeds."""
    seeds = spawn_seeds(root_seed, 2 * len(robot_counts) * instances)
    tasks = []
    for c, n in enumerate(robot_counts):
        for k in range(instances):
            idx = 2 * (c * instances + k)
            tasks.append({"run_id": f"n{n:02d}-i{k:03d}", "seed": seeds[idx], "instance_seed": seeds[idx + 1],
                          "n_robots": int(n), "instance": k, "base_probability": base_probability,
                          "region_probability": region_probability, "max_steps": max_steps})
    return tasks


def run_reproduction(out: str | Path, instances: int = 10, robot_counts: Sequence[int] = ROBOT_COUNTS, *,
                     executor: str = "process", scheduler: str | None = None, workers: int | None = None,
                     root_seed: int = 0, base_probability: float = 0.05, progress: bool = True) -> pd.DataFrame:
    """Run (or resume) the experiment into ``out/runs``; returns every row."""
    from ..experiments import run_tasks

    tasks = make_tasks(robot_counts, instances, root_seed, base_probability)
    return run_tasks(run_instance, tasks, Path(out) / "runs", executor=executor, scheduler=scheduler,
                     workers=workers, progress=progress)


def summarize(rows: pd.DataFrame) -> pd.DataFrame:
    """Fig. 6 aggregates per (robot count, variant).

    Columns: ``instances``, ``finished_share`` (no deadlock, all arrived), ``deadlocks``,
    ``mean_travel_time`` (s per robot, over instances where all variants finished),
    ``flips``, ``refused_flips``, ``decision_ms`` (per run), ``decision_ms_per_test``, ``collisions``.
    """
    ok = rows[rows["error"].isna()] if "error" in rows else rows
    ok = ok[ok["variant"].notna()]
    all_done = ok.groupby("run_id")["finished"].transform("all")
    common = ok[all_done]
    order = [v.name for v in ALL_VARIANTS]
    out = []
    for (n, variant), g in ok.groupby(["n_robots", "variant"]):
        c = common[(common["n_robots"] == n) & (common["variant"] == variant)]
        out.append({
            "n_robots": int(n), "variant": variant, "instances": len(g),
            "finished_share": float(g["finished"].mean()), "deadlocks": int(g["deadlock"].sum()),
            "mean_travel_time": float(c["mean_travel_time"].mean()) if len(c) else float("nan"),
            "common_instances": len(c),
            "flips": float(g["flips"].mean()), "refused_flips": float(g["refused_flips"].mean()),
            "decision_ms": float(1e3 * g["decision_seconds"].mean()),
            "decision_ms_per_test": float(g["decision_ms_per_test"].mean()) if g["flip_tests"].sum() else float("nan"),
            "collisions": int(g["collisions"].sum()),
        })
    table = pd.DataFrame(out)
    table["variant"] = pd.Categorical(table["variant"], order, ordered=True)
    return table.sort_values(["n_robots", "variant"]).reset_index(drop=True)


def markdown_table(summary: pd.DataFrame) -> str:
    """The Fig. 6 numbers as a markdown table."""
    head = ("| robots | variant | instances | finished w/o deadlock | mean travel time [s] | flips | refused flips "
            "| flip decision [ms/run] | [ms/test] | collisions |")
    lines = [head, "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in summary.itertuples():
        lines.append(
            f"| {r.n_robots} | {r.variant} | {r.instances} | {100 * r.finished_share:.0f}% | {_fmt(r.mean_travel_time, 2)} "
            f"| {r.flips:.1f} | {r.refused_flips:.1f} | {_fmt(r.decision_ms, 2)} | {_fmt(r.decision_ms_per_test, 3)} | {r.collisions} |"
        )
    return "\n".join(lines) + "\n"


def _fmt(v: float, digits: int) -> str:
    return "–" if not np.isfinite(v) else f"{v:.{digits}f}"


def example_trace(n_robots: int = 20, instance_seed: int = 1, seed: int = 1, variant: Variant | None = None):
    """One run of the experiment as a trace (for the Fig. 1-style animation)."""
    variant = variant or ALL_VARIANTS[-1]
    task = {"run_id": "example", "n_robots": n_robots, "instance_seed": instance_seed}
    spec, workspace, traj, _ = plan_instance(task)
    space = build_coordination_space(traj)
    run = make_executor(traj, space, workspace, variant, spec.disturbance.base_probability).run(seed, spec.simulation.max_steps)
    return execution_trace(traj, run, workspace, variant, seed, spec.disturbance.base_probability)
