"""``robofleet reproduce buavc``: Monte Carlo comparison of B-UAVC, BVC and inflated BVC.

Zhu, Brito & Alonso-Mora 2022, Sec. 6, on the authors' three-box setup (five robots in a
random antipodal swap, Σ = Σ_o = σ² I), as two shipped sweeps:

* ``buavc_noise``: method ∈ {buavc, bvc, bvc_inflated} × σ ∈ {0.05, 0.1, 0.15, 0.2} at
  δ = 0.1 (the grid key ``robots.sigma+workspace.obstacle_sigma`` ties Σ_o to Σ);
* ``buavc_delta``: B-UAVC × δ ∈ {0.01, 0.05, 0.1, 0.2} at σ = 0.1 — the empirical
  collision probability against the bound δ the chance constraint (Eq. 12) is built to
  respect.

Every row carries the avoidance family's collision frequencies on true positions
(``pair_step_rate``: colliding (pair, step) couples over all couples, the quantity the
per-step chance constraint bounds by δ; ``pair_rate``; ``obstacle_step_rate``;
``run_collided``). The tables add, per group, the pooled pair-step rate over all its runs
and its one-sided 95 % Clopper–Pearson upper bound: zero contacts in many pair-steps is
evidence of a small probability, not of zero.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from scipy.stats import beta

from ...core.errors import ConfigError
from ...scenarios import family
from ..reproduction import Budget, Frames, Reproduction
from ..report import markdown_table
from ..store import ERROR_COLUMN

NOISE_SWEEP = "buavc_noise"
DELTA_SWEEP = "buavc_delta"
SIGMA_KEY = "robots.sigma+workspace.obstacle_sigma"
"""The noise sweep's grid key: one σ for the robots' Σ and the obstacles' Σ_o."""

RESULT_KEYS = ["success", "n_robots", "n_steps", "run_collided", "pair_rate", "pair_step_rate",
               "obstacle_step_rate", "mean_travel_time", "deadlock_detections"]
"""The summary keys of each run the tables read."""
AGGREGATES = {
    "runs": ("seed", "size"), "success": ("success", "mean"), "run_collided": ("run_collided", "mean"),
    "pair_rate": ("pair_rate", "mean"), "pair_step_rate": ("pair_step_rate", "mean"),
    "obstacle_step_rate": ("obstacle_step_rate", "mean"), "mean_travel_time": ("mean_travel_time", "mean"),
    "deadlock_detections": ("deadlock_detections", "mean"),
    "pair_steps": ("pair_steps", "sum"), "pair_contacts": ("pair_contacts", "sum"),
}
TABLE_FORMATS = {
    "runs": "d", "success": ".0%", "run_collided": ".0%", "pair_rate": ".0%", "pair_step_pooled": ".2e",
    "pair_step_upper": ".2e", "obstacle_step_rate": ".2e", "mean_travel_time": ".1f", "deadlock_detections": ".1f",
}
TABLE_COLUMNS = ["runs", "success", "run_collided", "pair_rate", "pair_step_pooled", "pair_step_upper",
                 "obstacle_step_rate", "mean_travel_time", "deadlock_detections"]


def finished_rows(frame: pd.DataFrame, needed: list[str], sweep: str) -> pd.DataFrame:
    """The rows of runs that finished (``error`` unset), checked to carry ``needed`` columns
    (added empty when no run finished, so the tables come out empty).

    Raises
    ------
    ConfigError
        One line naming the sweep and the missing result keys.
    """
    ok = frame[frame[ERROR_COLUMN].isna()] if ERROR_COLUMN in frame else frame
    missing = [c for c in needed if c not in ok.columns]
    if len(ok) and missing:
        raise ConfigError(f"{sweep}: rows: expected the avoidance result keys {missing}, received rows without them")
    return ok.reindex(columns=[*ok.columns, *missing])


def pooled_upper_bound(events: float, trials: float, confidence: float = 0.95) -> float:
    """One-sided Clopper–Pearson upper bound of a probability from ``events`` in ``trials``.

    The ``confidence`` quantile of Beta(events + 1, trials − events); 1 when every trial
    was an event, ``nan`` without trials.
    """
    if trials <= 0:
        return float("nan")
    return 1.0 if events >= trials else float(beta.ppf(confidence, events + 1, trials - events))


def with_pair_steps(rows: pd.DataFrame) -> pd.DataFrame:
    """Add ``pair_steps`` (robot pairs × recorded states) and ``pair_contacts`` (colliding
    pair-steps, ``pair_step_rate × pair_steps``) to each run's row."""
    pair_steps = rows["n_robots"] * (rows["n_robots"] - 1) / 2 * (rows["n_steps"] + 1)
    return rows.assign(pair_steps=pair_steps, pair_contacts=rows["pair_step_rate"] * pair_steps)


def pooled_rates(table: pd.DataFrame) -> pd.DataFrame:
    """Add the pooled pair-step rate of each group and its 95 % upper bound."""
    upper = [pooled_upper_bound(round(c), t) for c, t in zip(table["pair_contacts"], table["pair_steps"])]
    return table.assign(pair_step_pooled=table["pair_contacts"] / table["pair_steps"], pair_step_upper=upper)


def group_table(rows: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Per-run means, pooled pair-step counts and bounds per group of ``keys``."""
    return pooled_rates(with_pair_steps(rows).groupby(keys).agg(**AGGREGATES).reset_index())


def tables(frames: Frames) -> dict[str, pd.DataFrame]:
    """``noise`` (per method × σ) and ``delta`` (per δ) aggregates of the two sweeps."""
    noise_rows = finished_rows(frames[NOISE_SWEEP], RESULT_KEYS, NOISE_SWEEP).rename(columns={SIGMA_KEY: "sigma"})
    delta_rows = finished_rows(frames[DELTA_SWEEP], RESULT_KEYS, DELTA_SWEEP)
    return {"noise": group_table(noise_rows, ["method", "sigma"]), "delta": group_table(delta_rows, ["delta"])}


def markdown(tables: dict[str, pd.DataFrame]) -> str:
    """The two tables as markdown (percentages for shares of runs)."""
    return (
        "Noise sweep (three boxes, 5 robots, δ = 0.1, Σ = Σ_o = σ² I):\n\n"
        + markdown_table(tables["noise"], ["method", "sigma"] + TABLE_COLUMNS, TABLE_FORMATS)
        + "\n\nThreshold sweep (B-UAVC, σ = 0.1): pooled per-pair-per-step collision rate and its 95 % upper bound against δ.\n\n"
        + markdown_table(tables["delta"], ["delta"] + TABLE_COLUMNS, TABLE_FORMATS) + "\n"
    )


def figures(tables: dict[str, pd.DataFrame], out: Path) -> list[Path]:
    """``buavc_comparison.png``: collisions, success and travel time against σ, and the
    pooled collision rate against δ (drawn by the family's figures module)."""
    viz = family("avoidance").viz_module()
    return [viz.plot_buavc_comparison(tables["noise"], tables["delta"], Path(out) / "buavc_comparison.png")]


REPRODUCTION = Reproduction(
    name="buavc",
    family="avoidance",
    paper="Zhu, Brito & Alonso-Mora 2022, Sec. 6 (Monte Carlo B-UAVC vs BVC vs inflated BVC)",
    description="three-box swap: collisions, success and travel time over noise σ per method; collision rate against δ",
    sweeps=(NOISE_SWEEP, DELTA_SWEEP),
    tables=tables,
    markdown=markdown,
    figures=figures,
    budgets={
        "smallest": Budget(seeds=1, overrides={"max_steps": 20}, grid={SIGMA_KEY: [0.1], "delta": [0.1]}),
        "default": Budget(seeds=20),
        "full": Budget(seeds=100),
    },
)
