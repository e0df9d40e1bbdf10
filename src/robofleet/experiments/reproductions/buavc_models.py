"""``robofleet reproduce buavc-models``: B-UAVC for every robot model of Zhu et al. 2022.

Zhu, Brito & Alonso-Mora 2022, Secs. 5–6: for each robot model a Monte Carlo over seeds
and localisation noise σ (Σ = σ² I for the robots, Σ_o = σ² I for the obstacles)
compares B-UAVC with BVC and inflated BVC, and with ORCA where it applies (holonomic
single integrators). One shipped sweep per model (in 3D each team carries its σ; one grid
key ``teams.0.sigma+teams.1.sigma+space3d.obstacle_sigma`` moves them together):

* single integrator (``avoidance/antipodal_swap``): buavc, bvc, bvc_inflated, orca;
* double integrator (``avoidance/double_integrator``, braking rule of Sec. 5.2);
* differential drive (``avoidance/diff_drive``, three projections of Sec. 5.3);
* quadrotor (``avoidance/quadrotors_3d``, MPC of Sec. 5.4 in 3D; a fifth of the seeds,
  a run costs 10–40 s against under 2 s in 2D);
* heterogeneous ground + air team (``avoidance/heterogeneous``; two fifths of the seeds).

Two threshold sweeps (B-UAVC, δ ∈ {0.01, 0.05, 0.1, 0.2}) on the double integrator and
the differential-drive robots give the empirical collision rate against δ. Per run:
success (every robot arrived and no contact at all), collisions on true positions
(pair-step rate, the quantity the chance constraint bounds; any contact in the run),
mean travel time, deadlock detections, and robots that never arrived (deadlock or
livelock).
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import pandas as pd

from ...scenarios import family
from ..reproduction import Budget, Frames, Reproduction
from ..report import markdown_table
from .buavc import SIGMA_KEY, finished_rows

NOISE_SWEEPS = {  # sweep: model
    "buavc_models_single_integrator": "single_integrator",
    "buavc_models_double_integrator": "double_integrator",
    "buavc_models_diff_drive": "diff_drive",
    "buavc_models_quadrotor": "quadrotor",
    "buavc_models_heterogeneous": "heterogeneous",
}
DELTA_SWEEPS = {
    "buavc_models_delta_double_integrator": "double_integrator",
    "buavc_models_delta_diff_drive": "diff_drive",
}
MODEL_ORDER = ("single_integrator", "double_integrator", "diff_drive", "quadrotor", "heterogeneous")
SIGMA_KEYS = (SIGMA_KEY, "teams.0.sigma+teams.1.sigma+space3d.obstacle_sigma")
"""Grid keys naming σ: 2D sweeps tie Σ_o to Σ, 3D sweeps tie both teams' σ to the boxes' σ_o."""
SEED_SHARES = {
    "buavc_models_quadrotor": 0.2,
    "buavc_models_heterogeneous": 0.4,
}
"""Share of the budget's seeds run by the costly 3D sweeps (MPC: 10–40 s a run, under 2 s in 2D)."""

RESULT_KEYS = ["success", "n_robots", "run_collided", "pair_step_rate", "obstacle_step_rate",
               "mean_travel_time", "deadlock_detections", "arrived"]
"""The summary keys of each run the tables read."""
AGGREGATES = {
    "runs": ("seed", "size"), "success": ("success", "mean"), "run_collided": ("run_collided", "mean"),
    "pair_step_rate": ("pair_step_rate", "mean"), "obstacle_step_rate": ("obstacle_step_rate", "mean"),
    "mean_travel_time": ("mean_travel_time", "mean"), "deadlock_detections": ("deadlock_detections", "mean"),
    "unfinished": ("unfinished", "mean"),
}
TABLE_FORMATS = {
    "runs": "d", "success": ".0%", "run_collided": ".0%", "pair_step_rate": ".1e", "obstacle_step_rate": ".1e",
    "mean_travel_time": ".1f", "deadlock_detections": ".1f", "unfinished": ".1f",
}
TABLE_COLUMNS = ["runs", "success", "run_collided", "pair_step_rate", "obstacle_step_rate", "mean_travel_time",
                 "deadlock_detections", "unfinished"]


def model_rows(frame: pd.DataFrame, sweep: str, model: str) -> pd.DataFrame:
    """The finished rows of one sweep, with ``model``, ``sigma`` (from the grid key naming
    σ, if any), ``success`` counting a run with any contact as failed, and ``unfinished``
    (robots not at their goal at the step limit)."""
    rows = finished_rows(frame, RESULT_KEYS, sweep)
    rows = rows.rename(columns={key: "sigma" for key in SIGMA_KEYS if key in rows})
    collided = rows["run_collided"].astype(bool)
    unfinished = (rows["n_robots"] * (1.0 - rows["arrived"])).round()
    return rows.assign(model=model, success=rows["success"].astype(bool) & ~collided, unfinished=unfinished)


def sweep_rows(frames: Frames, sweeps: Mapping[str, str]) -> pd.DataFrame:
    """The rows of ``sweeps`` (sweep → model) stacked into one frame."""
    return pd.concat([model_rows(frames[sweep], sweep, model) for sweep, model in sweeps.items()], ignore_index=True)


def tables(frames: Frames) -> dict[str, pd.DataFrame]:
    """``noise`` (per model × method × σ, in model order) and ``delta`` (per model × δ)."""
    noise = sweep_rows(frames, NOISE_SWEEPS).groupby(["model", "method", "sigma"]).agg(**AGGREGATES).reset_index()
    order = {m: k for k, m in enumerate(MODEL_ORDER)}
    noise = noise.sort_values(["model", "sigma", "method"], key=lambda c: c.map(order) if c.name == "model" else c)
    delta = sweep_rows(frames, DELTA_SWEEPS).groupby(["model", "delta"]).agg(**AGGREGATES).reset_index()
    return {"noise": noise.reset_index(drop=True), "delta": delta}


def markdown(tables: dict[str, pd.DataFrame]) -> str:
    """Both tables as markdown."""
    return ("Noise sweep (δ = 0.1; rates are means over runs; travel time in s over arrived robots; "
            "unfinished = robots not at their goal at the step limit):\n\n"
            + markdown_table(tables["noise"], ["model", "method", "sigma"] + TABLE_COLUMNS, TABLE_FORMATS)
            + "\n\nThreshold sweep (B-UAVC): per-step pair collision rate against δ.\n\n"
            + markdown_table(tables["delta"], ["model", "delta"] + TABLE_COLUMNS, TABLE_FORMATS) + "\n")


def figures(tables: dict[str, pd.DataFrame], out: Path) -> list[Path]:
    """``models_noise.png`` (collisions and success against σ per model) and
    ``models_delta.png`` (B-UAVC's pair-step collision rate against δ), drawn by the
    family's figures module."""
    viz, out = family("avoidance").viz_module(), Path(out)
    return [viz.plot_models_noise(tables["noise"], out / "models_noise.png"),
            viz.plot_models_delta(tables["delta"], out / "models_delta.png")]


REPRODUCTION = Reproduction(
    name="buavc-models",
    family="avoidance",
    paper="Zhu, Brito & Alonso-Mora 2022, Secs. 5-6 (B-UAVC for double integrators, differential drive, "
          "quadrotors and mixed teams vs BVC, inflated BVC and ORCA)",
    description="every robot model: collisions, success and unfinished robots over noise σ per method; collision rate against δ",
    sweeps=(*NOISE_SWEEPS, *DELTA_SWEEPS),
    tables=tables,
    markdown=markdown,
    figures=figures,
    budgets={
        "smallest": Budget(seeds=1, overrides={"max_steps": 10}, grid={SIGMA_KEY: [0.1], "delta": [0.1]}),
        "default": Budget(seeds=10),
        "full": Budget(seeds=40),
    },
    seed_shares=SEED_SHARES,
)
