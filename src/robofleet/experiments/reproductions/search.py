"""Fig. 7 of Yang 2017 (X. Yang, CCC 2017) and the coverage study behind its Section 3, declared.

* **Fig. 7** (``sweeps/search_fig7.yaml``): nine targets evenly spread (situation 1), 1 to
  13 robots starting at random border vertices, the four algorithms (LFP, RU, (1)&(3),
  (1),(2)&(3)); mean search time with 95 % confidence intervals. Run ``k`` uses the same
  seed — hence the same start vertices — for every algorithm and robot count (paired
  design: a sweep gives every grid point the same seeds).
* **Coverage study** (``sweeps/search_coverage.yaml``, situation 2): the proposed
  algorithm on the triangular, square and hexagonal grids fitted to the same area; the
  share of ``A_d`` within ``r_st`` of a visited vertex, which backs the paper's choice of
  the triangular grid. In situation 2 ``r_st`` does not change the routes, so
  ``sweeps/search_coverage_ranges.yaml`` judges the same routes (5 robots) at shorter
  target ranges too (violating Assumption 3.1.1).

Budgets: ``smallest`` (a smoke run: 3 robots, two target ranges, 2 seeds), ``default`` (50
seeds per point: 2,600 Fig. 7 runs and 50 coverage runs per grid and robot count),
``full`` (500 seeds per point: the paper's 26,000 Fig. 7 runs; the coverage study at 500 too).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ...core.trace import Trace
from ...scenarios import family, load_scenario, simulate
from ...search.spec import LABELS, Algorithm
from ..reproduction import Budget, Frames, Reproduction
from ..store import ERROR_COLUMN

FIG7_SWEEP = "search_fig7"
COVERAGE_SWEEP = "search_coverage"
RANGES_SWEEP = "search_coverage_ranges"
FIG7_ALGORITHMS = (Algorithm.LFP, Algorithm.RU, Algorithm.RULE1, Algorithm.PROPOSED)
ROUTES_SCENARIO, ROUTES_ROBOTS, ROUTES_SEED = "search/fig7", 3, 5
"""The run drawn as Figs. 5 and 6 (routes of every robot, and of robot 0)."""
Z95 = 1.959963984540054


def finished(frame: pd.DataFrame) -> pd.DataFrame:
    """The rows of runs that did not raise."""
    return frame[frame[ERROR_COLUMN].isna()] if ERROR_COLUMN in frame else frame


def mean_ci(values: pd.Series) -> tuple[float, float, int]:
    """Mean, the half-width of its normal-approximation 95 % confidence interval, and the count."""
    v = values.to_numpy(dtype=float)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return float("nan"), float("nan"), 0
    half = Z95 * v.std(ddof=1) / np.sqrt(len(v)) if len(v) > 1 else float("nan")
    return float(v.mean()), float(half), len(v)


def fig7_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Mean search time (s) with 95 % CI per algorithm and number of robots (Fig. 7),
    with the mean collisions, the completed share and the success share."""
    rows = []
    for (alg, n), g in finished(df).groupby(["algorithm", "n_robots"]):
        mean, half, count = mean_ci(g["search_time"])
        rows.append({"algorithm": alg, "label": LABELS[Algorithm(alg)], "n_robots": int(n), "mean_time": mean, "ci95": half,
                     "runs": count, "mean_collisions": float(g["collisions"].mean()), "completed": float(g["completed"].mean()),
                     "success": float(g["success"].mean())})
    return pd.DataFrame(rows).sort_values(["algorithm", "n_robots"]).reset_index(drop=True)


def coverage_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Mean detected share of ``A_d`` (± 95 % CI), worst run, grid limit, visited share and
    search time per grid kind and number of robots."""
    rows = []
    for (kind, n), g in finished(df).groupby(["grid.kind", "n_robots"], sort=False):
        share, half, count = mean_ci(g["detected_share"])
        rows.append({"grid": kind, "n_robots": int(n), "detected_share": share, "ci95": half, "min_detected_share": float(g["detected_share"].min()),
                     "grid_limit_share": float(g["grid_limit_share"].mean()), "visited_share": float(g["visited_share"].mean()),
                     "mean_time": float(g["search_time"].mean()), "accessible_vertices": int(g["accessible_vertices"].iloc[0]),
                     "runs": count})
    return pd.DataFrame(rows)


def range_column(r_st_over_a: float) -> str:
    """Column name of the detected share at ``r_st = r_st_over_a · a``."""
    return f"detected_at_rst_{r_st_over_a:.2f}a"


def coverage_range_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Mean detected share per grid kind and number of robots (rows) and target range
    (columns ``detected_at_rst_<r>a``; the Fig. 7 area has ``a = 1``)."""
    means = finished(df).groupby(["grid.kind", "n_robots", "ranges.r_st"], sort=False)["detected_share"].mean()
    wide = means.unstack("ranges.r_st")
    wide = wide[sorted(wide.columns)]
    wide.columns = [range_column(r) for r in wide.columns]
    return wide.reset_index().rename(columns={"grid.kind": "grid"})


def tables(frames: Frames) -> dict[str, pd.DataFrame]:
    """``fig7``, ``coverage``, ``coverage_ranges`` and ``runs`` (per-sweep counts) from the sweeps' rows."""
    return {"fig7": fig7_summary(frames[FIG7_SWEEP]), "coverage": coverage_summary(frames[COVERAGE_SWEEP]),
            "coverage_ranges": coverage_range_summary(frames[RANGES_SWEEP]), "runs": run_counts(frames)}


def run_counts(frames: Frames) -> pd.DataFrame:
    """Per sweep: runs, failed runs and the summed run time (``wall_seconds``, one core)."""
    rows = [{"sweep": name, "runs": len(f), "failed": int(len(f) - len(finished(f))),
             "run_seconds": float(finished(f)["wall_seconds"].sum())} for name, f in frames.items()]
    return pd.DataFrame(rows)


def fig7_markdown(summary: pd.DataFrame) -> str:
    """Markdown table: one row per number of robots, one column per algorithm (mean ± CI, s)."""
    algs = [a for a in FIG7_ALGORITHMS if a.value in set(summary["algorithm"])]
    head = "| robots | " + " | ".join(LABELS[a] for a in algs) + " |\n|---:|" + "---:|" * len(algs) + "\n"
    lines = []
    for n in sorted(summary["n_robots"].unique()):
        cells = []
        for a in algs:
            row = summary[(summary["algorithm"] == a.value) & (summary["n_robots"] == n)]
            cells.append(f"{row['mean_time'].iloc[0]:.1f} ± {row['ci95'].iloc[0]:.1f}" if len(row) else "")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return head + "\n".join(lines) + "\n"


def coverage_markdown(summary: pd.DataFrame) -> str:
    """Markdown table of the coverage study."""
    head = ("| grid | robots | accessible vertices | detected share of A_d (mean ± CI) | worst run | grid limit | visited share | search time (s) |\n"
            "|---|---:|---:|---:|---:|---:|---:|---:|\n")
    lines = [f"| {r.grid} | {r.n_robots} | {r.accessible_vertices} | {r.detected_share:.4f} ± {r.ci95:.4f} | {r.min_detected_share:.4f} | "
             f"{r.grid_limit_share:.4f} | {r.visited_share:.3f} | {r.mean_time:.1f} |" for r in summary.itertuples()]
    return head + "\n".join(lines) + "\n"


def coverage_range_markdown(summary: pd.DataFrame) -> str:
    """Markdown table: mean detected share per grid when the same routes are judged with
    other target-sensing ranges (below ``a + r_safe`` Assumption 3.1.1 fails)."""
    cols = [c for c in summary.columns if c.startswith("detected_at_rst_")]
    ranges = [c.removeprefix("detected_at_rst_") for c in cols]
    head = "| grid | robots | " + " | ".join(f"r_st = {r}" for r in ranges) + " |\n|---|---:|" + "---:|" * len(cols) + "\n"
    lines = [f"| {r['grid']} | {r['n_robots']} | " + " | ".join(f"{r[c]:.4f}" for c in cols) + " |" for _, r in summary.iterrows()]
    return head + "\n".join(lines) + "\n"


def runs_markdown(counts: pd.DataFrame) -> str:
    """One line per sweep: runs, failures and summed run time."""
    return "".join(f"- `{r.sweep}`: {r.runs} runs ({r.failed} failed), {r.run_seconds:.0f} s of run time on one core\n"
                   for r in counts.itertuples())


def markdown(t: dict[str, pd.DataFrame]) -> str:
    """The text of ``table.md``: Fig. 7, the coverage study and its target-range table."""
    return ("### Fig. 7: mean search time (s, ± 95 % CI), nine targets\n\n" + fig7_markdown(t["fig7"])
            + "\n### Coverage study (situation 2, proposed algorithm)\n\n" + coverage_markdown(t["coverage"])
            + "\nThe same routes (5 robots) judged with other target-sensing ranges (a = 1):\n\n"
            + coverage_range_markdown(t["coverage_ranges"])
            + "\n" + runs_markdown(t["runs"]))


def routes_trace() -> Trace:
    """The run drawn as Figs. 5–6: the Fig. 7 scenario with 3 robots at seed 5."""
    return simulate(load_scenario(ROUTES_SCENARIO, {"robots.count": ROUTES_ROBOTS}), seed=ROUTES_SEED)


def figures(t: dict[str, pd.DataFrame], out: Path) -> list[Path]:
    """``fig7.png``, ``coverage.png`` (detected share against ``r_st``), and the routes of
    one run (``fig5_routes.png``, ``fig6_route.png``, its trace in ``fig5_trace/``)."""
    viz = family("search").viz_module()
    trace = routes_trace()
    trace.save(out / "fig5_trace")
    return [viz.plot_fig7(t["fig7"], out / "fig7.png"), viz.plot_coverage_ranges(t["coverage_ranges"], out / "coverage.png"),
            viz.plot_routes(trace, out / "fig5_routes.png"),
            viz.plot_routes(trace, out / "fig6_route.png", robots=[0], title="Route of robot 0")]


REPRODUCTION = Reproduction(
    name="search",
    family="search",
    paper="Yang 2017 (CCC), Fig. 7 and the grid coverage study of Section 3",
    description="search time of LFP, RU, (1)&(3), (1),(2)&(3) for 1-13 robots; detected share of A_d on T/S/H grids",
    sweeps=(FIG7_SWEEP, COVERAGE_SWEEP, RANGES_SWEEP),
    tables=tables,
    markdown=markdown,
    figures=figures,
    budgets={
        "smallest": Budget(seeds=2, grid={"robots.count": [3], "ranges.r_st": [1.31, 0.6]}),
        "default": Budget(seeds=50),
        "full": Budget(seeds=500),
    },
)
