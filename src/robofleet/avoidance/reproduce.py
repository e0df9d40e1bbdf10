"""``robofleet reproduce buavc``: Monte Carlo comparison of B-UAVC, BVC and inflated BVC.

Two sweeps on the authors' three-box setup (five robots, random antipodal swap, Σ and
Σ_o = σ² I):

* noise: method ∈ {buavc, bvc, bvc_inflated} × σ ∈ ``sigmas`` at δ = 0.1;
* threshold: B-UAVC × δ ∈ ``deltas`` at σ = 0.1 — the empirical collision probability
  against the bound δ it is designed to respect.

Each run reports, besides the standard summary, the empirical collision probability per
robot pair and step (what the chance constraint bounds), per robot pair over the run,
and per run.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..core import metrics
from ..core.rng import spawn_seeds
from ..experiments.report import markdown_table
from ..scenarios import load_scenario, shipped_scenario, simulate

SCENARIO = "three_boxes.yaml"
SIGMAS = (0.05, 0.1, 0.15, 0.2)
DELTAS = (0.01, 0.05, 0.1, 0.2)
METHODS = ("buavc", "bvc", "bvc_inflated")



def plan(seeds: int, root_seed: int = 0, sigmas=SIGMAS, deltas=DELTAS) -> list[dict]:
    """Task dicts of both sweeps (the same seeds for every method and noise level)."""
    seed_list = spawn_seeds(root_seed, seeds)
    tasks = []
    for k, seed in enumerate(seed_list):
        for sigma in sigmas:
            for method in METHODS:
                tasks.append({"sweep": "noise", "method": method, "sigma": sigma, "delta": 0.1, "seed": seed, "replicate": k})
        for delta in deltas:
            tasks.append({"sweep": "delta", "method": "buavc", "sigma": 0.1, "delta": delta, "seed": seed, "replicate": k})
    for t in tasks:
        t["run_id"] = f"{t['sweep']}-{t['method']}-s{t['sigma']}-d{t['delta']}-r{t['replicate']}"
    return tasks


def run_one(task: dict) -> dict:
    """Simulate one task and return its row (module-level so worker processes can import it)."""
    overrides = {"method": task["method"], "delta": task["delta"], "robots.sigma": task["sigma"], "workspace.obstacle_sigma": task["sigma"]}
    spec = load_scenario(shipped_scenario("avoidance", SCENARIO), overrides=overrides)
    trace = simulate(spec, seed=task["seed"])
    row = {k: v for k, v in trace.summary().items() if np.isscalar(v)}
    row.update(collision_probabilities(trace))
    return row


def collision_probabilities(trace) -> dict:
    """Empirical collision frequencies of one run (true positions).

    ``pair_step_rate``: colliding (pair, step) couples over all couples — the quantity the
    per-step chance constraint bounds by δ; ``pair_rate``: share of pairs that ever
    collided; ``run_collided``: any robot–robot or robot–obstacle contact.
    """
    pos, r = trace.positions, float(trace.metadata["radius"])
    n, steps = pos.shape[1], len(pos)
    contacts, _ = metrics.pair_contacts(pos, r)
    pairs = n * (n - 1) / 2
    obstacle_hits, _ = metrics.obstacle_contacts(pos, r, trace.workspace)
    return {
        "pair_step_rate": len(contacts) / (pairs * steps) if pairs else 0.0,
        "pair_rate": len({(int(i), int(j)) for _, i, j in contacts}) / pairs if pairs else 0.0,
        "obstacle_step_rate": len(obstacle_hits) / (n * steps),
        "run_collided": bool(len(contacts) or len(obstacle_hits)),
    }


def pooled_upper_bound(events: float, trials: float, confidence: float = 0.95) -> float:
    """One-sided Clopper–Pearson upper bound of a probability from ``events`` in ``trials``."""
    from scipy.stats import beta

    if trials <= 0:
        return float("nan")
    return 1.0 if events >= trials else float(beta.ppf(confidence, events + 1, trials - events))


def tables(frame: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Aggregates of the noise sweep (per method × σ) and the δ sweep (per δ).

    Besides per-run means, the pooled per-pair-per-step collision rate over all runs of a
    group and its one-sided 95 % Clopper–Pearson upper bound (``pair_step_upper``): zero
    contacts in many pair-steps is evidence of a small probability, not of zero.
    """
    ok = (frame[frame["error"].isna()] if "error" in frame else frame).copy()
    ok["pair_steps"] = ok["n_robots"] * (ok["n_robots"] - 1) / 2 * (ok["n_steps"] + 1)
    ok["pair_contacts"] = ok["pair_step_rate"] * ok["pair_steps"]
    agg = {
        "runs": ("seed", "size"), "success": ("success", "mean"), "run_collided": ("run_collided", "mean"),
        "pair_rate": ("pair_rate", "mean"), "pair_step_rate": ("pair_step_rate", "mean"),
        "obstacle_step_rate": ("obstacle_step_rate", "mean"), "mean_travel_time": ("mean_travel_time", "mean"),
        "deadlock_detections": ("deadlock_detections", "mean"),
    }
    agg.update(pair_steps=("pair_steps", "sum"), pair_contacts=("pair_contacts", "sum"))
    noise = ok[ok["sweep"] == "noise"].groupby(["method", "sigma"]).agg(**agg).reset_index()
    delta = ok[ok["sweep"] == "delta"].groupby(["delta"]).agg(**agg).reset_index()
    for table in (noise, delta):
        table["pair_step_pooled"] = table["pair_contacts"] / table["pair_steps"]
        table["pair_step_upper"] = [pooled_upper_bound(round(c), t) for c, t in zip(table["pair_contacts"], table["pair_steps"])]
    return noise, delta


TABLE_FORMATS = {
    "runs": "d", "success": ".0%", "run_collided": ".0%", "pair_rate": ".0%", "pair_step_pooled": ".2e",
    "pair_step_upper": ".2e", "obstacle_step_rate": ".2e", "mean_travel_time": ".1f", "deadlock_detections": ".1f",
}
TABLE_COLUMNS = ["runs", "success", "run_collided", "pair_rate", "pair_step_pooled", "pair_step_upper",
                 "obstacle_step_rate", "mean_travel_time", "deadlock_detections"]


def markdown(noise: pd.DataFrame, delta: pd.DataFrame) -> str:
    """The two tables as markdown (percentages for rates)."""
    return (
        "Noise sweep (three boxes, 5 robots, δ = 0.1, Σ = Σ_o = σ² I):\n\n"
        + markdown_table(noise, ["method", "sigma"] + TABLE_COLUMNS, TABLE_FORMATS)
        + "\n\nThreshold sweep (B-UAVC, σ = 0.1): pooled per-pair-per-step collision rate and its 95 % upper bound against δ.\n\n"
        + markdown_table(delta, ["delta"] + TABLE_COLUMNS, TABLE_FORMATS) + "\n"
    )


def reproduce(out: str | Path = "results/buavc", seeds: int = 20, executor: str = "process", scheduler: str | None = None,
              workers: int | None = None, progress: bool = True) -> dict:
    """Run both sweeps into ``out/runs`` (resumable), then write ``table.md`` and plots."""
    from ..experiments import run_tasks
    from ..viz.avoidance import plot_reproduction

    out = Path(out)
    frame = run_tasks(run_one, plan(seeds), out / "runs", executor=executor, scheduler=scheduler, workers=workers, progress=progress)
    noise, delta = tables(frame)
    (out / "table.md").write_text(markdown(noise, delta))
    figure = plot_reproduction(noise, delta, out / "buavc_comparison.png")
    return {"frame": frame, "noise": noise, "delta": delta, "table": out / "table.md", "figure": figure}
