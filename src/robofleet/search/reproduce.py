"""Reproduction of Fig. 7 of paper 002, and the coverage study behind Section 3.

* **Fig. 7**: nine targets evenly spread (situation 1), 1 to 13 robots starting at random
  border vertices, ``runs`` runs per point, the four algorithms (LFP, RU, (1)&(3),
  (1),(2)&(3)); mean search time with 95 % confidence intervals. Run ``k`` uses the same
  seed — hence the same start vertices — for every algorithm and robot count (paired
  design). Tasks batch ``batch`` runs so that per-task overhead stays small.
* **Coverage study** (situation 2): the proposed algorithm on the triangular, square and
  hexagonal grids fitted to the same area; the share of ``A_d`` within ``r_st`` of a visited
  vertex, which backs the paper's choice of the triangular grid.

Both go through :func:`robofleet.experiments.run_tasks` (serial, process or Dask executors,
resumable Parquet store). Task functions are module-level, so they pickle; each task
advances its batch of runs in lockstep (:func:`~.simulation.run_search_batch`), which gives
exactly the rows of separate runs at a fraction of the per-step overhead.
"""

from __future__ import annotations

import time
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.rng import spawn_seeds
from ..scenarios import shipped_scenario
from .grids import GridKind
from .scenario import build_problem, coverage_probe
from .simulation import LABELS, Algorithm, run_search_batch

FIG7_ALGORITHMS = (Algorithm.LFP, Algorithm.RU, Algorithm.RULE1, Algorithm.PROPOSED)
FIG7_ROBOTS = tuple(range(1, 14))
COVERAGE_GRIDS = (GridKind.TRIANGULAR, GridKind.SQUARE, GridKind.HEXAGONAL)
#: target-sensing ranges (units of a) at which the coverage study also evaluates the visited sets
COVERAGE_RANGES = (0.6, 0.7, 0.8, 0.9, 1.0)
ROOT_SEED = 2017
Z95 = 1.959963984540054



@lru_cache(maxsize=64)
def _spec(path: str, overrides: tuple):
    from ..scenarios import load_scenario

    return load_scenario(path, dict(overrides))


def run_seeds(root_seed: int, first: int, count: int) -> list[int]:
    """Seeds of runs ``first … first + count − 1`` of a study (independent of batching)."""
    return spawn_seeds(root_seed, first + count)[first:]


def fig7_task(task: dict) -> list[dict]:
    """One batch of Fig. 7 runs: ``task`` has ``scenario``, ``algorithm``, ``n_robots``,
    ``first_run``, ``n_runs``, ``root_seed``. Returns one row per run."""
    spec = _spec(task["scenario"], (("robots.count", int(task["n_robots"])), ("algorithm", task["algorithm"]),
                                    ("require_guarantee", False)))
    seeds = run_seeds(int(task["root_seed"]), int(task["first_run"]), int(task["n_runs"]))
    outcomes = run_search_batch([build_problem(spec, seed) for seed in seeds], spec.algorithm, seeds)
    return [{"run_index": int(task["first_run"]) + k, "run_seed": seed, **o.results} for k, (seed, o) in enumerate(zip(seeds, outcomes))]


def coverage_task(task: dict) -> list[dict]:
    """One batch of situation-2 runs on grid ``grid_kind``; adds ``detected_share`` and the
    share reachable in principle (all reachable accessible vertices visited)."""
    spec = _spec(task["scenario"], (("robots.count", int(task["n_robots"])), ("algorithm", "proposed"),
                                    ("situation", 2), ("grid.kind", task["grid_kind"]), ("require_guarantee", False)))
    rows = []
    grid = spec.built_grid()
    probe = coverage_probe(grid, spec.ranges.r_st)
    probes = {range_column(r): coverage_probe(grid, r * grid.a) for r in COVERAGE_RANGES}
    seeds = run_seeds(int(task["root_seed"]), int(task["first_run"]), int(task["n_runs"]))
    problems = [build_problem(spec, seed) for seed in seeds]
    outcomes = run_search_batch(problems, Algorithm.PROPOSED, seeds)
    for k, (seed, problem, outcome) in enumerate(zip(seeds, problems, outcomes)):
        best = grid.reachable_from(problem.starts) & grid.accessible
        rows.append({
            "run_index": int(task["first_run"]) + k, "run_seed": seed, **outcome.results,
            "detected_share": probe.detected_share(outcome.visited),
            "grid_limit_share": probe.detected_share(best),
            "accessible_vertices": int(grid.accessible.sum()),
            **{col: p.detected_share(outcome.visited) for col, p in probes.items()},
        })
    return rows


def range_column(r_st_over_a: float) -> str:
    """Column name of the detected share evaluated at ``r_st = r_st_over_a · a``."""
    return f"detected_at_rst_{r_st_over_a:.2f}a"


def batched(prefix: str, runs: int, batch: int, root_seed: int, **fields) -> list[dict]:
    """Tasks covering runs ``0 … runs−1`` in batches; ``seed`` is the first run's seed."""
    seeds = spawn_seeds(root_seed, runs)
    return [{"run_id": f"{prefix}-b{first:04d}", "seed": seeds[first], "first_run": first,
             "n_runs": min(batch, runs - first), "root_seed": root_seed, **fields}
            for first in range(0, runs, batch)]


def fig7_tasks(runs: int = 500, batch: int = 25, root_seed: int = ROOT_SEED, scenario: str | Path | None = None,
               robots=FIG7_ROBOTS, algorithms=FIG7_ALGORITHMS) -> list[dict]:
    """Tasks of the Fig. 7 sweep (``len(algorithms) · len(robots) · runs`` runs)."""
    path = str(scenario or shipped_scenario("search", "fig7.yaml"))
    return [task for alg in algorithms for n in robots
            for task in batched(f"fig7-{Algorithm(alg).value}-n{n:02d}", runs, batch, root_seed,
                                scenario=path, algorithm=Algorithm(alg).value, n_robots=n)]


def coverage_tasks(runs: int = 50, batch: int = 25, root_seed: int = ROOT_SEED + 1, scenario: str | Path | None = None,
                   robots=(1, 3, 5)) -> list[dict]:
    """Tasks of the coverage study (three grids × ``robots`` × ``runs``)."""
    path = str(scenario or shipped_scenario("search", "fig7.yaml"))
    return [task for kind in COVERAGE_GRIDS for n in robots
            for task in batched(f"coverage-{kind.value}-n{n:02d}", runs, batch, root_seed,
                                scenario=path, grid_kind=kind.value, n_robots=n)]


def mean_ci(values: pd.Series) -> tuple[float, float, float]:
    """Mean and the half-width of its normal-approximation 95 % confidence interval."""
    v = values.to_numpy(dtype=float)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return float("nan"), float("nan"), 0
    half = Z95 * v.std(ddof=1) / np.sqrt(len(v)) if len(v) > 1 else float("nan")
    return float(v.mean()), float(half), len(v)


def fig7_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Mean search time (s) with 95 % CI per algorithm and number of robots."""
    ok = df[df["error"].isna()] if "error" in df else df
    rows = []
    for (alg, n), g in ok.groupby(["algorithm", "n_robots"]):
        mean, half, count = mean_ci(g["search_time"])
        rows.append({"algorithm": alg, "label": LABELS[Algorithm(alg)], "n_robots": int(n), "mean_time": mean, "ci95": half,
                     "runs": count, "mean_collisions": float(g["collisions"].mean()), "completed": float(g["completed"].mean())})
    return pd.DataFrame(rows).sort_values(["algorithm", "n_robots"]).reset_index(drop=True)


def coverage_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Mean detected share, visited share and search time per grid kind and number of robots."""
    ok = df[df["error"].isna()] if "error" in df else df
    rows = []
    for (kind, n), g in ok.groupby(["grid_kind", "n_robots"]):
        share, half, count = mean_ci(g["detected_share"])
        rows.append({"grid": kind, "n_robots": int(n), "detected_share": share, "ci95": half,
                     "min_detected_share": float(g["detected_share"].min()), "grid_limit_share": float(g["grid_limit_share"].mean()),
                     "visited_share": float(g["visited_share"].mean()), "mean_time": float(g["search_time"].mean()),
                     "accessible_vertices": int(g["accessible_vertices"].iloc[0]), "runs": count,
                     **{range_column(r): float(g[range_column(r)].mean()) for r in COVERAGE_RANGES}})
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
    """Markdown table: mean detected share per grid when the same routes are judged with a
    shorter target-sensing range (violating Assumption 3.1.1)."""
    cols = [range_column(r) for r in COVERAGE_RANGES]
    head = "| grid | robots | " + " | ".join(f"r_st = {r:.1f} a" for r in COVERAGE_RANGES) + " |\n|---|---:|" + "---:|" * len(cols) + "\n"
    lines = [f"| {r['grid']} | {r['n_robots']} | " + " | ".join(f"{r[c]:.4f}" for c in cols) + " |" for _, r in summary.iterrows()]
    return head + "\n".join(lines) + "\n"


def reproduce_search(out: str | Path = "results/search", runs: int = 500, coverage_runs: int = 50, *, executor: str = "process",
                     scheduler: str | None = None, workers: int | None = None, progress: bool = True, batch: int = 25) -> dict:
    """Run the Fig. 7 sweep and the coverage study into ``out``; write ``table.md``.

    Returns a dict with the two summaries (DataFrames), the wall times (s) and the paths
    written. Plots are written by :func:`robofleet.viz.search.write_reproduction_figures`.
    """
    from ..experiments import run_tasks

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    fig7 = run_tasks(fig7_task, fig7_tasks(runs, batch), out / "fig7_runs", executor=executor, scheduler=scheduler,
                     workers=workers, progress=progress)
    fig7_seconds = time.perf_counter() - t0
    t1 = time.perf_counter()
    cov = run_tasks(coverage_task, coverage_tasks(coverage_runs, batch), out / "coverage_runs", executor=executor,
                    scheduler=scheduler, workers=workers, progress=progress)
    coverage_seconds = time.perf_counter() - t1
    fig7_sum, cov_sum = fig7_summary(fig7), coverage_summary(cov)
    fig7_sum.to_csv(out / "fig7_summary.csv", index=False)
    cov_sum.to_csv(out / "coverage_summary.csv", index=False)
    n_runs = int(len(fig7))
    text = ("### Fig. 7: mean search time (s, ± 95 % CI), nine targets\n\n" + fig7_markdown(fig7_sum)
            + f"\n{n_runs} runs in {fig7_seconds:.0f} s wall time ({executor} executor).\n\n"
            + "### Coverage study (situation 2, proposed algorithm)\n\n" + coverage_markdown(cov_sum)
            + "\nThe same routes judged with shorter target-sensing ranges:\n\n" + coverage_range_markdown(cov_sum)
            + f"\n{len(cov)} runs in {coverage_seconds:.0f} s wall time.\n")
    (out / "table.md").write_text(text)
    return {"fig7": fig7_sum, "coverage": cov_sum, "fig7_seconds": fig7_seconds, "coverage_seconds": coverage_seconds,
            "fig7_runs": n_runs, "table": out / "table.md", "out": out}
