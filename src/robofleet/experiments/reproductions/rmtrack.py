"""``robofleet reproduce rmtrack``: Fig. 6 of the label-flipping deadlock paper on the X-plus-corridor map.

One shipped sweep, ``rmtrack_fig6``: robot count ∈ {5, 10, 15, 20} × method ∈ {RMTRACK,
RMTRACK+TFF, RMTRACK+TFA} × deadlock check ∈ {off, on} × seeds. The scenario's
``robots.instance_seed`` is null, so each seed draws one random instance (starts and goals
in the flows' boxes, trajectories from the prioritized planner) and one set of
disturbances (one random stream per robot and step), and the six variants of a seed run on
that same plan with those same disturbances: a paired comparison. Every row carries the
plan's digest (``plan_id``), so the pairing is visible in the results.

Aggregates per (robot count, variant), as the authors' release computed them (Fig. 6 a–d):
average travel time per robot over the instances where all six variants finished, the
flip-decision time per flip test, the number of flips, the share of instances finished
without deadlock.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ...coordination.plan_execution import ALL_VARIANTS
from ...scenarios import load_scenario, simulate
from ...viz import coordination as viz
from ..reproduction import Budget, Frames, Reproduction
from ..report import markdown_table
from ..store import ERROR_COLUMN

SWEEP = "rmtrack_fig6"
COUNT_KEY = "robots.count"
"""The sweep's grid key of the robot count (failed runs carry it, not ``n_robots``)."""
EXAMPLE_SCENARIO = "coordination/x_corridor_20"
EXAMPLE_SEED = 1
VARIANT_ORDER = [v.name for v in ALL_VARIANTS]
INSTANCE = ["n_robots", "seed"]
"""The columns that identify one instance: the six variants of a seed share it."""

DISPLAY = {
    "n_robots": "robots", "variant": "variant", "instances": "instances", "finished_share": "finished w/o deadlock",
    "mean_travel_time": "mean travel time [s]", "flips": "flips", "refused_flips": "refused flips",
    "decision_ms": "flip decision [ms/run]", "decision_ms_per_test": "[ms/test]", "collisions": "collisions",
}
FORMATS = {
    "robots": "d", "instances": "d", "finished w/o deadlock": ".0%", "mean travel time [s]": ".2f", "flips": ".1f",
    "refused flips": ".1f", "flip decision [ms/run]": ".2f", "[ms/test]": ".3f", "collisions": "d",
}


def finished_runs(frame: pd.DataFrame) -> pd.DataFrame:
    """Rows of runs that did not raise, with ``decision_ms_per_test`` (NaN without flip tests)
    and ``common`` (all variants of the instance ran and finished)."""
    ok = frame[frame[ERROR_COLUMN].isna()].copy() if ERROR_COLUMN in frame else frame.copy()
    tests = ok["flip_tests"].where(ok["flip_tests"] > 0)
    ok["decision_ms_per_test"] = 1e3 * ok["decision_seconds"] / tests
    grouped = ok.groupby(INSTANCE)["finished"]
    ok["common"] = grouped.transform("all") & (grouped.transform("size") == ok["variant"].nunique())
    return ok


def fig6_summary(frame: pd.DataFrame) -> pd.DataFrame:
    """Fig. 6 aggregates per (robot count, variant).

    Columns: ``instances``, ``finished_share`` (all arrived, hence no deadlock),
    ``deadlocks``, ``mean_travel_time`` (s per robot, over the instances where every
    variant finished), ``common_instances``, ``flips``, ``refused_flips`` (means per run),
    ``decision_ms`` (per run), ``decision_ms_per_test``, ``collisions`` (sum), ``paired``
    (each instance executed one plan in every variant), ``failed`` (runs that raised).
    """
    ok = finished_runs(frame)
    failed = frame[frame[ERROR_COLUMN].notna()] if ERROR_COLUMN in frame else frame.iloc[:0]
    paired = ok.groupby(INSTANCE)["plan_id"].nunique().groupby("n_robots").max() == 1
    rows = []
    for (n, variant), g in ok.groupby(["n_robots", "variant"]):
        common = g[g["common"]]
        rows.append({
            "n_robots": int(n), "variant": variant, "instances": len(g),
            "finished_share": float(g["finished"].mean()), "deadlocks": int(g["deadlock"].sum()),
            "mean_travel_time": float(common["mean_travel_time"].mean()) if len(common) else float("nan"),
            "common_instances": len(common), "flips": float(g["flips"].mean()),
            "refused_flips": float(g["refused_flips"].mean()), "decision_ms": float(1e3 * g["decision_seconds"].mean()),
            "decision_ms_per_test": float(g["decision_ms_per_test"].mean()), "collisions": int(g["collisions"].sum()),
            "paired": bool(paired.get(n, False)), "failed": int((failed[COUNT_KEY] == n).sum()) if COUNT_KEY in failed else 0,
        })
    return sort_variants(pd.DataFrame(rows, columns=list(DISPLAY) + ["deadlocks", "common_instances", "paired", "failed"]))


def sort_variants(table: pd.DataFrame) -> pd.DataFrame:
    """Rows by robot count, then in the order RMTRACK, RMTRACK (checked), ..., RMTRACK+TFA (checked)."""
    rank = table["variant"].map({v: i for i, v in enumerate(VARIANT_ORDER)})
    return table.assign(_rank=rank).sort_values(["n_robots", "_rank"]).drop(columns="_rank").reset_index(drop=True)


def tables(frames: Frames) -> dict[str, pd.DataFrame]:
    """``fig6``: the aggregates of :func:`fig6_summary` over the sweep's rows."""
    return {"fig6": fig6_summary(frames[SWEEP])}


def markdown(tables: dict[str, pd.DataFrame]) -> str:
    """The Fig. 6 numbers as a markdown table."""
    table = tables["fig6"]
    shown = table[list(DISPLAY)].rename(columns=DISPLAY)
    note = ("Mean travel time over the instances where all six variants finished; flip decision = wall time of "
            "the flip tests plus, for checked variants, the cycle tests.")
    return markdown_table(shown, formats=FORMATS) + "\n\n" + note + "\n"


def figures(tables: dict[str, pd.DataFrame], out: Path) -> list[Path]:
    """``fig6.png`` (the four panels), and one example run at the largest robot count:
    ``example/`` (its trace), ``plan.png`` (map, plan, final state) and ``animation.gif``."""
    out = Path(out)
    table = tables["fig6"]
    files = [viz.plot_fig6(table, out / "fig6.png")]
    n_robots = int(table["n_robots"].max()) if len(table) else 20
    trace = simulate(load_scenario(EXAMPLE_SCENARIO, overrides={"robots.count": n_robots}), seed=EXAMPLE_SEED)
    trace.save(out / "example")
    files += [viz.plot_trace(trace, out / "plan.png"), viz.animate_trace(trace, out / "animation.gif")]
    return files


REPRODUCTION = Reproduction(
    name="rmtrack",
    family="coordination",
    paper="deadlock theory for label flipping (anonymous, 2021), Fig. 6: RMTRACK vs label flipping (TFF, TFA) with and without the deadlock check",
    description="X-plus-corridor map, 5-20 robots: travel time, flip-decision time, flips and finished share per variant",
    sweeps=(SWEEP,),
    tables=tables,
    markdown=markdown,
    figures=figures,
    budgets={
        "smallest": Budget(seeds=1, grid={"robots.count": [5]}),
        "default": Budget(seeds=5),
        "full": Budget(seeds=10),
    },
)
