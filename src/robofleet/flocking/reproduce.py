"""Reproduction of the experiments of Sec. 4.2 (Figs. 9-11) and a comparison of the variants.

Setup as in Sec. 4.2: followers and leader start uniformly in a 512 × 512 square, every
follower has a random local frame (rotation and chirality) and a speed v_f ~ U(0.5, 5)
units per move; the leader's speed and turn rate are set within conditions (1)-(2)
(``"auto"``, :mod:`.leader`), it turns with probability 1/20 per move. ξ = 2 Σ_i k^{f_i}.

* **Fig. 11**: Δ_e(t) and Δ_r(t) of the basic algorithm under ASYNC for the wedge (6),
  line (4), spread (10) and random (2-8 points) patterns, over ``seeds`` seeds
  (:func:`curve_task`, one row per sampled time).
* **Comparison**: basic vs stripe vs hula-hoop vs randomized under FSYNC, SSYNC and ASYNC
  on the wedge and spread patterns, same seeds for every cell (:func:`comparison_task`).
* **Figs. 9-10**: traces of one wedge and one spread run (plots and animations in
  :mod:`robofleet.viz.flocking`).

Everything runs through :func:`robofleet.experiments.run_tasks`, so the store resumes
and the executor (serial, process, dask) does not change the numbers.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.rng import spawn_seeds
from ..experiments.report import markdown_table
from ..scenarios import shipped_scenario

FIG11_PATTERNS = ("wedge", "line", "spread", "random")
COMPARED_ALGORITHMS = ("basic", "stripe", "hula_hoop", "randomized")
SCHEDULERS = ("fsync", "ssync", "async")
COMPARED_PATTERNS = ("wedge", "spread")
ROOT_SEED = 2001
CURVE_STRIDE = 5



@lru_cache(maxsize=64)
def _spec(pattern: str, algorithm: str, scheduler: str, duration: float):
    from ..scenarios import load_scenario

    overrides = {"pattern.kind": pattern, "algorithm.kind": algorithm, "scheduler.kind": scheduler, "duration": duration,
                 "name": f"{pattern}-{algorithm}-{scheduler}"}
    return load_scenario(shipped_scenario("flocking", "wedge_async.yaml"), overrides)


def run_one(task: dict):
    """Simulate the scenario described by a task (pattern, algorithm, scheduler, duration, seed)."""
    from .scenario import simulate

    spec = _spec(task["pattern"], task.get("algorithm", "basic"), task.get("scheduler", "async"), float(task["duration"]))
    return simulate(spec, seed=int(task["seed"]))


def curve_task(task: dict) -> list[dict]:
    """Fig. 11 rows: Δ_e(t), Δ_r(t) every ``CURVE_STRIDE`` samples, plus the run's ξ."""
    trace = run_one(task)
    a = trace.arrays
    idx = np.arange(0, len(a["time"]), CURVE_STRIDE)
    r = trace.results
    return [{"t": float(a["time"][i]), "delta_e": float(a["delta_e"][i]), "delta_r": float(a["delta_r"][i]),
             "xi": float(r["xi"]), "n_followers": int(r["n_followers"])} for i in idx]


SUMMARY_KEYS = ("xi", "n_followers", "delta_e_final", "delta_r_final", "delta_e_tail", "delta_r_tail", "convergence_time_e",
                "convergence_time_r", "converged_e", "converged_r", "slot_changes", "cycles", "seen_moving_share",
                "condition_1", "condition_2", "condition_3", "condition_4", "leader_v_leader", "leader_omega_leader")


def comparison_task(task: dict) -> dict:
    """One comparison cell: the scalar results of a run."""
    r = run_one(task).results
    return {k: r[k] for k in SUMMARY_KEYS}


def curve_tasks(seeds: int, duration: float) -> list[dict]:
    return [{"run_id": f"fig11-{p}-{i:03d}", "seed": s, "pattern": p, "duration": duration}
            for p in FIG11_PATTERNS for i, s in enumerate(spawn_seeds(ROOT_SEED, seeds))]


def comparison_tasks(seeds: int, duration: float) -> list[dict]:
    return [{"run_id": f"cmp-{p}-{a}-{sc}-{i:03d}", "seed": s, "pattern": p, "algorithm": a, "scheduler": sc, "duration": duration}
            for p in COMPARED_PATTERNS for a in COMPARED_ALGORITHMS for sc in SCHEDULERS
            for i, s in enumerate(spawn_seeds(ROOT_SEED + 1, seeds))]


def fig11_table(curves: pd.DataFrame) -> pd.DataFrame:
    """Per pattern: time from which Δ_e (Δ_r) stays ≤ ξ (median over seeds, share of seeds),
    share of the last third of the run with Δ_r ≤ ξ, final values."""
    rows = []
    present = [p for p in FIG11_PATTERNS if p in set(curves["pattern"])]
    for pattern, g in ((p, curves[curves["pattern"] == p]) for p in present):
        per_run = []
        for _, run in g.groupby("run_id"):
            run = run.sort_values("t")
            last = run["t"] >= run["t"].max() * 2 / 3
            per_run.append({
                "share_r": float((run["delta_r"][last] <= run["xi"].iloc[0]).mean()),
                "te": _stays_below(run["t"].to_numpy(), run["delta_e"].to_numpy(), run["xi"].iloc[0]),
                "tr": _stays_below(run["t"].to_numpy(), run["delta_r"].to_numpy(), run["xi"].iloc[0]),
                "de": run["delta_e"].iloc[-1], "dr": run["delta_r"].iloc[-1], "xi": run["xi"].iloc[0],
            })
        d = pd.DataFrame(per_run)
        rows.append({"pattern": pattern, "runs": len(d), "ξ (median)": d["xi"].median(),
                     "Δe ≤ ξ: share": (d["te"].notna()).mean(), "Δe ≤ ξ from t (median)": d["te"].median(),
                     "Δr ≤ ξ: share": (d["tr"].notna()).mean(), "Δr ≤ ξ from t (median)": d["tr"].median(),
                     "time with Δr ≤ ξ, last third (mean)": d["share_r"].mean(),
                     "final Δe (median)": d["de"].median(), "final Δr (median)": d["dr"].median()})
    return pd.DataFrame(rows)


def _stays_below(t, v, xi) -> float:
    from .metrics import convergence_time

    return convergence_time(t, v, xi)


def comparison_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per pattern × scheduler × algorithm: convergence share and time, slot changes, final errors."""
    df = df[df["error"].isna()] if "error" in df else df
    g = df.groupby(["pattern", "scheduler", "algorithm"], sort=False)
    out = g.agg(runs=("seed", "size"), converged_e=("converged_e", "mean"), t_conv_e=("convergence_time_e", "median"),
                converged_r=("converged_r", "mean"), slot_changes=("slot_changes", "mean"),
                final_de=("delta_e_final", "median"), final_dr=("delta_r_final", "median")).reset_index()
    order = {k: i for i, k in enumerate(SCHEDULERS)}
    alg_order = {k: i for i, k in enumerate(COMPARED_ALGORITHMS)}
    out = out.sort_values(["pattern", "scheduler", "algorithm"], key=lambda c: c.map(order) if c.name == "scheduler" else c.map(alg_order) if c.name == "algorithm" else c)
    return out.rename(columns={"converged_e": "Δe ≤ ξ: share", "t_conv_e": "Δe ≤ ξ from t (median)", "converged_r": "Δr ≤ ξ: share",
                               "slot_changes": "slot changes (mean)", "final_de": "final Δe (median)", "final_dr": "final Δr (median)"})


def markdown(df: pd.DataFrame) -> str:
    """A markdown table (numbers to 3 significant digits)."""
    return markdown_table(df)


def reproduce_flocking(out: str | Path, seeds: int = 10, *, duration: float = 1500.0, compare_seeds: int | None = None,
                       executor: str = "process", scheduler: str | None = None, workers: int | None = None,
                       progress: bool = True) -> dict:
    """Run the Fig. 11 curves and the comparison; write ``table.md``; return the data frames.

    Plots, traces and animations are drawn by the CLI with :mod:`robofleet.viz.flocking`.
    """
    from ..experiments import run_tasks

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    curves = run_tasks(curve_task, curve_tasks(seeds, duration), out / "fig11_runs", executor=executor,
                       scheduler=scheduler, workers=workers, progress=progress)
    comp = run_tasks(comparison_task, comparison_tasks(compare_seeds or seeds, duration), out / "comparison_runs",
                     executor=executor, scheduler=scheduler, workers=workers, progress=progress)
    curves = curves[curves["error"].isna()] if "error" in curves else curves
    t11, tc = fig11_table(curves), comparison_table(comp)
    text = ("## Fig. 11: basic algorithm, ASYNC\n\n" + markdown(t11) +
            "\n\n## Comparison of the variants (wedge and spread)\n\n" + markdown(tc) + "\n")
    (out / "table.md").write_text(text)
    return {"curves": curves, "comparison": comp, "fig11_table": t11, "comparison_table": tc, "table": out / "table.md"}
