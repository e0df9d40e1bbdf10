"""``robofleet reproduce buavc-models``: B-UAVC for every robot model of paper 003.

For each model a Monte Carlo over seeds and localisation noise σ (Σ = σ² I, obstacles
Σ_o = σ_o² I as in the scenario file) compares B-UAVC with BVC and inflated BVC, and
with ORCA where it applies (holonomic single integrators):

* ``single_integrator``: ``avoidance/antipodal_swap.yaml`` — buavc, bvc, bvc_inflated, orca;
* ``double_integrator``: ``avoidance_models/double_integrator.yaml`` (braking rule);
* ``diff_drive``: ``avoidance_models/diff_drive.yaml`` (three projections);
* ``quadrotor``: ``avoidance_models/quadrotors_3d.yaml`` (MPC, 3D; fewer seeds, it is costly);
* ``heterogeneous``: ``avoidance_models/heterogeneous.yaml`` (ground + air; fewest seeds).

A threshold sweep (B-UAVC, δ ∈ ``DELTAS``) on the double integrator and the
differential-drive robots gives the empirical collision rate against δ. Per run:
success, collisions (pair-step rate, the quantity the chance constraint bounds; any
contact in the run), mean travel time, deadlock detections, and robots that never
arrived (deadlock or livelock).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..core import metrics
from ..core.rng import spawn_seeds
from ..experiments.report import markdown_table
from ..scenarios import load_scenario, shipped_scenario, simulate
from .models_simulation import box_distance

MODELS = {
    # name: (scenario, methods, sigmas, seed share, noise overrides)
    "single_integrator": ("avoidance/antipodal_swap.yaml", ("buavc", "bvc", "bvc_inflated", "orca"), (0.05, 0.1, 0.2), 1.0),
    "double_integrator": ("avoidance_models/double_integrator.yaml", ("buavc", "bvc", "bvc_inflated"), (0.05, 0.1, 0.2), 1.0),
    "diff_drive": ("avoidance_models/diff_drive.yaml", ("buavc", "bvc", "bvc_inflated"), (0.03, 0.06, 0.12), 1.0),
    "quadrotor": ("avoidance_models/quadrotors_3d.yaml", ("buavc", "bvc", "bvc_inflated"), (0.05, 0.1), 0.2),
    "heterogeneous": ("avoidance_models/heterogeneous.yaml", ("buavc", "bvc", "bvc_inflated"), (0.04,), 0.4),
}
DELTAS = (0.01, 0.05, 0.1, 0.2)


def model_scenario(model: str) -> Path:
    """The shipped scenario file of ``model`` (``MODELS[model][0]`` is ``family/file``)."""
    family, name = MODELS[model][0].split("/")
    return shipped_scenario(family, name)
DELTA_MODELS = ("double_integrator", "diff_drive")


def plan(seeds: int, root_seed: int = 0, models=tuple(MODELS)) -> list[dict]:
    """Task dicts: every (model, method, σ) and the δ sweeps, same seeds across methods."""
    tasks = []
    for model in models:
        _, methods, sigmas, share = MODELS[model]
        seed_list = spawn_seeds(root_seed, max(1, int(round(seeds * share))))
        for k, seed in enumerate(seed_list):
            for sigma in sigmas:
                for method in methods:
                    tasks.append({"sweep": "noise", "model": model, "method": method, "sigma": sigma, "delta": 0.1, "seed": seed, "replicate": k})
            if model in DELTA_MODELS:
                for delta in DELTAS:
                    tasks.append({"sweep": "delta", "model": model, "method": "buavc", "sigma": MODELS[model][2][1], "delta": delta, "seed": seed, "replicate": k})
    for t in tasks:
        t["run_id"] = f"{t['sweep']}-{t['model']}-{t['method']}-s{t['sigma']}-d{t['delta']}-r{t['replicate']}"
    return tasks


def overrides(task: dict, spec_mapping_teams: int) -> dict:
    """Scenario overrides of a task: method, δ, and σ for the robots (every team) and obstacles."""
    out = {"method": task["method"], "delta": task["delta"]}
    if spec_mapping_teams:
        for k in range(spec_mapping_teams):
            out[f"teams.{k}.sigma"] = task["sigma"]
        out["space3d.obstacle_sigma"] = task["sigma"]
    else:
        out["robots.sigma"] = task["sigma"]
        out["workspace.obstacle_sigma"] = task["sigma"]
    return out


def run_one(task: dict) -> dict:
    """Simulate one task and return its row (module level: worker processes import it)."""
    path = model_scenario(task["model"])
    teams = len(load_scenario(path).teams or [])
    spec = load_scenario(path, overrides=_teams_overrides(path, overrides(task, teams)))
    trace = simulate(spec, seed=task["seed"])
    row = {k: v for k, v in trace.summary().items() if np.isscalar(v)}
    row.update(collision_rates(trace))
    row["unfinished"] = int(round(row["n_robots"] * (1.0 - row["arrived"])))
    return row


def _teams_overrides(path, flat: dict) -> dict:
    """Dotted ``teams.k.sigma`` overrides cannot index a list; rewrite them on the list."""
    team_keys = {k: v for k, v in flat.items() if k.startswith("teams.")}
    if not team_keys:
        return flat
    import yaml

    teams = yaml.safe_load(Path(path).read_text())["teams"]
    for key, value in team_keys.items():
        _, k, field = key.split(".")
        teams[int(k)][field] = value
    out = {k: v for k, v in flat.items() if not k.startswith("teams.")}
    out["teams"] = teams
    return out


def collision_rates(trace) -> dict:
    """Empirical collision frequencies of one run on TRUE positions (2D or 3D).

    ``pair_step_rate``: colliding (pair, step) couples over all couples — bounded by δ per
    step by the chance constraint; ``run_collided``: any robot–robot or robot–obstacle contact.
    """
    pos, r = trace.positions, float(trace.metadata["radius"])
    n, steps = pos.shape[1], len(pos)
    contacts, _ = metrics.pair_contacts(pos, r)
    pairs = n * (n - 1) / 2
    if trace.workspace is not None:
        obstacle_hits = len(metrics.obstacle_contacts(pos, r, trace.workspace)[0])
    elif trace.metadata.get("boxes"):
        boxes = trace.metadata["boxes"]
        d = box_distance(pos, np.array([b["center"] for b in boxes]), np.array([b["size"] for b in boxes]), np.array([b["yaw"] for b in boxes]))
        obstacle_hits = int((d.min(axis=2) < r - metrics.CONTACT_TOL).sum())
    else:
        obstacle_hits = 0
    return {
        "pair_step_rate": len(contacts) / (pairs * steps) if pairs else 0.0,
        "obstacle_step_rate": obstacle_hits / (n * steps),
        "run_collided": bool(len(contacts) or obstacle_hits),
    }


AGG = {
    "runs": ("seed", "size"), "success": ("success", "mean"), "run_collided": ("run_collided", "mean"),
    "pair_step_rate": ("pair_step_rate", "mean"), "obstacle_step_rate": ("obstacle_step_rate", "mean"),
    "mean_travel_time": ("mean_travel_time", "mean"), "deadlock_detections": ("deadlock_detections", "mean"),
    "unfinished": ("unfinished", "mean"),
}


def tables(frame: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Aggregates: per (model, method, σ) and per (model, δ)."""
    ok = frame[frame["error"].isna()] if "error" in frame else frame
    ok = ok.assign(success=ok["success"].astype(bool) & ~ok["run_collided"].astype(bool))  # a run with any contact failed
    noise = ok[ok["sweep"] == "noise"].groupby(["model", "method", "sigma"]).agg(**AGG).reset_index()
    delta = ok[ok["sweep"] == "delta"].groupby(["model", "delta"]).agg(**AGG).reset_index()
    order = {m: k for k, m in enumerate(MODELS)}
    noise = noise.sort_values(["model", "sigma", "method"], key=lambda c: c.map(order) if c.name == "model" else c)
    return noise.reset_index(drop=True), delta


MODEL_TABLE_FORMATS = {
    "runs": "d", "success": ".0%", "run_collided": ".0%", "pair_step_rate": ".1e", "obstacle_step_rate": ".1e",
    "mean_travel_time": ".1f", "deadlock_detections": ".1f", "unfinished": ".1f",
}
MODEL_TABLE_COLUMNS = ["runs", "success", "run_collided", "pair_step_rate", "obstacle_step_rate", "mean_travel_time",
                       "deadlock_detections", "unfinished"]


def markdown(noise: pd.DataFrame, delta: pd.DataFrame) -> str:
    """Both tables as markdown."""
    return ("Noise sweep (δ = 0.1; rates are means over runs; travel time in s over arrived robots; "
            "unfinished = robots not at their goal at the step limit):\n\n"
            + markdown_table(noise, ["model", "method", "sigma"] + MODEL_TABLE_COLUMNS, MODEL_TABLE_FORMATS)
            + "\n\nThreshold sweep (B-UAVC): per-step pair collision rate against δ.\n\n"
            + markdown_table(delta, ["model", "delta"] + MODEL_TABLE_COLUMNS, MODEL_TABLE_FORMATS) + "\n")


def reproduce(out: str | Path = "results/buavc-models", seeds: int = 10, executor: str = "process", scheduler: str | None = None,
              workers: int | None = None, progress: bool = True, models=tuple(MODELS), animate: bool = True) -> dict:
    """Run the sweeps into ``out/runs`` (resumable), then write ``table.md``, plots and GIFs."""
    from ..experiments import run_tasks
    from ..viz.avoidance_models import animate_run, plot_models

    out = Path(out)
    frame = run_tasks(run_one, plan(seeds, models=models), out / "runs", executor=executor, scheduler=scheduler, workers=workers, progress=progress)
    noise, delta = tables(frame)
    (out / "table.md").write_text(markdown(noise, delta))
    figures = plot_models(noise, delta, out)
    gifs = []
    if animate:
        for name, model in (("diff_drive.gif", "diff_drive"), ("quadrotors_3d.gif", "quadrotor")):
            trace = simulate(load_scenario(model_scenario(model)), seed=1)
            gifs.append(animate_run(trace, out / name))
    return {"frame": frame, "noise": noise, "delta": delta, "table": out / "table.md", "figures": figures, "gifs": gifs}
