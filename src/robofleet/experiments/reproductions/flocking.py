"""``robofleet reproduce flocking``: Figs. 9-11 of Gervasi & Prencipe 2001 and a comparison of the variants.

Setup of Sec. 4.2 (the shipped scenario ``flocking/wedge_async``): followers and leader
start uniformly in a 512 × 512 square, every follower has a random local frame (rotation
and chirality) and a speed v_f ~ U(0.5, 5); the leader's speed and turn rate are set
inside conditions (1)-(2) of Sec. 3.2 and it starts or stops turning with probability
1/20 per move; ξ = 2 Σ_i k^{f_i}. Two shipped sweeps:

* ``flocking_fig11``: the basic algorithm under ASYNC for the wedge (6 followers), line
  (4), spread (10) and random (2-8 points) patterns; the same seeds for every pattern.
  Table ``fig11``: per pattern, the share of runs and the (median) time from which Δ_e
  (Δ_r) stays ≤ ξ, the share of the last third of the run with Δ_r ≤ ξ, final values.
  Figure ``fig11_delta.png``: Δ_e(t) and Δ_r(t), median and 10-90 % band over seeds.
* ``flocking_comparison``: basic vs stripe vs hula-hoop vs randomized under FSYNC, SSYNC
  and ASYNC on the wedge and spread patterns, the same seeds in every cell. Table
  ``comparison`` and figure ``comparison.png``.

Figs. 9-10 are the traces of one wedge and one spread run (``fig9_wedge``,
``fig10_spread``: plot, animation and the saved trace).

A sweep row holds the run's summary (scalars), not its Δ curves: the Fig. 11 figure
re-simulates the runs of the ``fig11_runs`` table from their seeds (the seed rule makes
them the same runs; each is checked against its row).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ...core.config import SpecModel, read_mapping
from ...core.errors import ConfigError
from ...scenarios import catalogue, load_scenario, simulate
from ...viz import flocking as viz
from ..reproduction import Budget, Frames, Reproduction
from ..report import markdown_table
from ..store import ERROR_COLUMN
from ..sweep import expand_overrides

FIG11_SWEEP = "flocking_fig11"
COMPARISON_SWEEP = "flocking_comparison"
FIG11_PATTERNS = ("wedge", "line", "spread", "random")
SCHEDULERS = ("fsync", "ssync", "async")
COMPARED_ALGORITHMS = ("basic", "stripe", "hula_hoop", "randomized")
GRID_COLUMNS = {"pattern.kind": "pattern", "scheduler.kind": "scheduler", "algorithm.kind": "algorithm"}
"""Grid paths of the sweeps and the names the tables give them."""
TRACE_RUNS = (("fig9_wedge", "wedge"), ("fig10_spread", "spread"))
"""Figs. 9-10: the traces drawn, by file stem and pattern."""
TRACE_SEED = 9
CURVE_STRIDE = 5
"""The Fig. 11 curves keep every 5th sample."""

RUN_COLUMNS = ["pattern", "seed", "duration", "run_id", "xi", "convergence_time_e", "convergence_time_r",
               "delta_e_final", "delta_r_final"]
"""The per-run table ``fig11_runs`` (what the Fig. 11 figure re-simulates)."""
FIG11_AGGREGATES = {
    "runs": ("seed", "size"), "ξ (median)": ("xi", "median"),
    "Δe ≤ ξ: share": ("converged_e", "mean"), "Δe ≤ ξ from t (median)": ("convergence_time_e", "median"),
    "Δr ≤ ξ: share": ("converged_r", "mean"), "Δr ≤ ξ from t (median)": ("convergence_time_r", "median"),
    "time with Δr ≤ ξ, last third (mean)": ("delta_r_within_xi_last_third", "mean"),
    "final Δe (median)": ("delta_e_final", "median"), "final Δr (median)": ("delta_r_final", "median"),
}
COMPARISON_AGGREGATES = {
    "runs": ("seed", "size"), "Δe ≤ ξ: share": ("converged_e", "mean"),
    "Δe ≤ ξ from t (median)": ("convergence_time_e", "median"), "Δr ≤ ξ: share": ("converged_r", "mean"),
    "slot changes (mean)": ("slot_changes", "mean"), "final Δe (median)": ("delta_e_final", "median"),
    "final Δr (median)": ("delta_r_final", "median"),
}


def finished_rows(frame: pd.DataFrame, sweep: str) -> pd.DataFrame:
    """The rows of runs that finished, the grid columns named as in :data:`GRID_COLUMNS`.

    The runs' own ``pattern`` / ``algorithm`` / ``scheduler`` results give way to the grid
    values (a random pattern's name, ``random<n>``, differs from its kind).

    Raises
    ------
    ConfigError
        When the rows lack a column the tables read.
    """
    ok = frame[frame[ERROR_COLUMN].isna()] if ERROR_COLUMN in frame else frame
    needed = ["pattern.kind", "duration", "converged_e", "convergence_time_e", "delta_e_final"]
    missing = [c for c in needed if c not in ok.columns]
    if len(ok) and missing:
        raise ConfigError(f"{sweep}: rows: expected the flocking grid and result columns {missing}, received rows without them")
    return ok.drop(columns=[c for c in GRID_COLUMNS.values() if c in ok]).rename(columns=GRID_COLUMNS)


def ordered(table: pd.DataFrame, column: str, order: tuple[str, ...]) -> pd.DataFrame:
    """``table`` sorted (stably) by ``column`` in the given ``order`` of values."""
    rank = {value: i for i, value in enumerate(order)}
    return table.sort_values(column, key=lambda c: c.map(rank), kind="stable")


def fig11_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Per pattern: convergence share and median time of Δ_e and Δ_r to ξ (t_1 of Def. 3.4),
    the share of the last third with Δ_r ≤ ξ, ξ and the final values (medians over seeds)."""
    table = rows.groupby("pattern", sort=False).agg(**FIG11_AGGREGATES).reset_index()
    return ordered(table, "pattern", FIG11_PATTERNS).reset_index(drop=True)


def comparison_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Per pattern × scheduler × algorithm: convergence share and time, slot changes, final errors."""
    table = rows.groupby(["pattern", "scheduler", "algorithm"], sort=False).agg(**COMPARISON_AGGREGATES).reset_index()
    table = ordered(ordered(table, "algorithm", COMPARED_ALGORITHMS), "scheduler", SCHEDULERS)
    return table.sort_values("pattern", kind="stable", key=lambda c: c.map({p: i for i, p in enumerate(FIG11_PATTERNS)})).reset_index(drop=True)


def tables(frames: Frames) -> dict[str, pd.DataFrame]:
    """``fig11`` and ``comparison`` (the tables of ``table.md``) and ``fig11_runs`` (one row per Fig. 11 run)."""
    fig11 = finished_rows(frames[FIG11_SWEEP], FIG11_SWEEP)
    comparison = finished_rows(frames[COMPARISON_SWEEP], COMPARISON_SWEEP)
    runs = ordered(fig11[RUN_COLUMNS], "pattern", FIG11_PATTERNS).reset_index(drop=True)
    return {"fig11": fig11_table(fig11), "comparison": comparison_table(comparison), "fig11_runs": runs}


def markdown(tables: dict[str, pd.DataFrame]) -> str:
    """The Fig. 11 and comparison tables as markdown (numbers to 3 significant digits)."""
    return ("## Fig. 11: basic algorithm, ASYNC\n\n" + markdown_table(tables["fig11"], formats={"runs": "d"}) +
            "\n\n## Comparison of the variants (wedge and spread)\n\n" +
            markdown_table(tables["comparison"], formats={"runs": "d"}) + "\n")


def fig11_scenario(pattern: str, duration: float) -> SpecModel:
    """The Fig. 11 sweep's scenario (with its fixed overrides) for one pattern and horizon."""
    data, source = read_mapping(catalogue.path(FIG11_SWEEP, "sweeps"))
    scenario = catalogue.resolve(data["scenario"], "scenarios", Path(source).parent)
    fixed = expand_overrides(data.get("overrides") or {})
    return load_scenario(scenario, {**fixed, "pattern.kind": pattern, "duration": float(duration)})


def delta_curves(runs: pd.DataFrame) -> pd.DataFrame:
    """Δ_e(t), Δ_r(t) of every run of ``runs`` (every :data:`CURVE_STRIDE`-th sample), re-simulated
    from its seed; columns ``pattern, run_id, t, delta_e, delta_r, xi``.

    Raises
    ------
    ConfigError
        If a re-simulated run does not end as its sweep row says (not the same run).
    """
    blocks = []
    for run in runs.itertuples(index=False):
        trace = simulate(fig11_scenario(run.pattern, run.duration), seed=int(run.seed))
        if not np.isclose(trace.results["delta_e_final"], run.delta_e_final, rtol=1e-12, equal_nan=True):
            raise ConfigError(f"{FIG11_SWEEP}: run {run.run_id}: expected the re-simulated run to end with Δe = "
                              f"{run.delta_e_final!r} as in its row, received {trace.results['delta_e_final']!r}")
        a, keep = trace.arrays, slice(None, None, CURVE_STRIDE)
        blocks.append(pd.DataFrame({"pattern": run.pattern, "run_id": run.run_id, "t": a["time"][keep],
                                    "delta_e": a["delta_e"][keep], "delta_r": a["delta_r"][keep], "xi": run.xi}))
    return pd.concat(blocks, ignore_index=True)


def trace_figures(duration: float, out: Path) -> list[Path]:
    """Figs. 9-10: one wedge and one spread run (seed :data:`TRACE_SEED`): trace, plot, animation."""
    files = []
    for stem, pattern in TRACE_RUNS:
        trace = simulate(fig11_scenario(pattern, duration), seed=TRACE_SEED)
        files.append(trace.save(out / f"{stem}_trace"))
        files += [viz.plot_trace(trace, out / f"{stem}.png"), viz.animate_trace(trace, out / f"{stem}.gif")]
    return files


def figures(tables: dict[str, pd.DataFrame], out: Path) -> list[Path]:
    """``fig11_delta.png`` (Fig. 11), ``comparison.png`` and the Figs. 9-10 traces."""
    out = Path(out)
    runs = tables["fig11_runs"]
    files = []
    if len(runs):
        files.append(viz.plot_delta_curves(delta_curves(runs), out / "fig11_delta.png"))
        files += trace_figures(float(runs["duration"].max()), out)
    if len(tables["comparison"]):
        files.append(viz.plot_comparison(tables["comparison"], out / "comparison.png"))
    return files


REPRODUCTION = Reproduction(
    name="flocking",
    family="flocking",
    paper="Gervasi & Prencipe 2001, Sec. 4.2 (Figs. 9-11) and the variants of Secs. 5.2, 5.3, 6.4",
    description="Δe/Δr convergence of the basic algorithm per pattern under ASYNC; basic vs stripe vs hula-hoop vs randomized per scheduler",
    sweeps=(FIG11_SWEEP, COMPARISON_SWEEP),
    tables=tables,
    markdown=markdown,
    figures=figures,
    budgets={
        "smallest": Budget(seeds=1, grid={"duration": [15], "scheduler.kind": ["fsync", "async"], "algorithm.kind": ["basic", "hula_hoop"]}),
        "default": Budget(seeds=10),
        "full": Budget(seeds=30),
    },
)
