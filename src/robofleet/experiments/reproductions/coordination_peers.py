"""``robofleet reproduce coordination-peers``: label flipping against its strongest peers.

Two shipped sweeps run the same five methods on the same plans and disturbances (paired
seeds: each seed draws one instance, plans it once, and every method executes that plan
under that seed's disturbances):

* ``coordination_peers_fig6`` — the instances of Fig. 6 of the label-flipping deadlock
  paper (X-plus-corridor map, 5/10/15/20 robots);
* ``coordination_peers_grid`` — warehouse-like grid instances (8 × 7 shelves, 50/100/200
  robots between random pick stations, planned by the family's prioritized planner).

Methods: RMTRACK; RMTRACK+TFF and RMTRACK+TFA with the segment-graph deadlock check;
BTPG (:mod:`robofleet.coordination.btpg`); the optimal orders within a horizon
(:mod:`robofleet.coordination.optimal`). The disturbance model is the paper's (p = 0.85
in a region, 0.05 elsewhere, one draw per robot and step).

Aggregates per (map, robot count, method): the share of runs that finished without
deadlock or contact; over the instances where all five methods finished, the mean travel
time, the mean *unnecessary waiting* (travel time above the delay-only lower bound, every
robot alone under its own disturbances) and the share of RMTRACK's unnecessary waiting
the method removes (``1 − ΣW / ΣW_RMTRACK`` over those instances); the flips, the
decision time per step and per run; BTPG's switchable obstacles and the optimal
method's decisions whose node budget ran out.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ...coordination.metrics import waiting_removed_share
from ...viz import coordination as viz
from ..reproduction import Budget, Frames, Reproduction
from ..report import markdown_table
from ..store import ERROR_COLUMN

SWEEPS = {"coordination_peers_fig6": "X-plus-corridor (Fig. 6)", "coordination_peers_grid": "warehouse grid"}
BASELINE = "RMTRACK"
METHOD_ORDER = ["RMTRACK", "RMTRACK+TFF (checked)", "RMTRACK+TFA (checked)", "BTPG", "optimal"]
SHOWN_NAMES = {"RMTRACK (checked)": "RMTRACK"}
"""RMTRACK changes no label, so its deadlock check never acts: it is shown without the suffix."""
INSTANCE = ["map", "n_robots", "seed"]
COUNT_KEY, METHOD_KEY = "robots.count", "policy.method"
"""The sweeps' grid keys (a run that raised carries them, not ``n_robots`` or ``variant``)."""
METHOD_KEYS = ["rmtrack", "tff", "tfa", "btpg", "optimal"]
"""``policy.method`` of each entry of :data:`METHOD_ORDER`."""

DISPLAY = {
    "map": "map", "n_robots": "robots", "method": "method", "instances": "runs", "success_share": "finished, no contact",
    "mean_travel_time": "mean travel time [s]", "unnecessary_waiting": "unnecessary waiting [s/robot]",
    "waiting_removed": "waiting removed vs RMTRACK", "flips": "flips", "decision_ms_per_step": "decision [ms/step]",
    "decision_ms": "decision [ms/run]", "switchable": "BTPG switchable", "exhausted_share": "budget ran out",
}
FORMATS = {
    "robots": "d", "runs": "d", "finished, no contact": ".0%", "mean travel time [s]": ".2f",
    "unnecessary waiting [s/robot]": ".2f", "waiting removed vs RMTRACK": ".0%", "flips": ".1f",
    "decision [ms/step]": ".3f", "decision [ms/run]": ".1f", "BTPG switchable": ".0%", "budget ran out": ".0%",
}


def runs(frames: Frames) -> pd.DataFrame:
    """The rows of both sweeps that did not raise, with ``map``, the shown ``method`` and
    ``common`` (every method of the instance ran and finished without contact)."""
    parts = []
    for sweep, name in SWEEPS.items():
        frame = frames.get(sweep, pd.DataFrame())
        ok = frame[frame[ERROR_COLUMN].isna()] if ERROR_COLUMN in frame else frame
        parts.append(ok.assign(map=name))
    rows = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()
    if rows.empty:
        return rows
    rows["method"] = rows["variant"].replace(SHOWN_NAMES)
    grouped = rows.groupby(INSTANCE)["success"]
    rows["common"] = grouped.transform("all") & (grouped.transform("size") == rows["method"].nunique())
    return rows


def failures(frames: Frames) -> dict[tuple[str, int, str], int]:
    """Runs that raised, per (map, robot count, method)."""
    counts: dict[tuple[str, int, str], int] = {}
    for sweep, name in SWEEPS.items():
        frame = frames.get(sweep, pd.DataFrame())
        if ERROR_COLUMN not in frame or COUNT_KEY not in frame:
            continue
        bad = frame[frame[ERROR_COLUMN].notna()]
        for (n, method), g in bad.groupby([COUNT_KEY, METHOD_KEY]):
            shown = dict(zip(METHOD_KEYS, METHOD_ORDER)).get(method, method)
            counts[(name, int(n), shown)] = len(g)
    return counts


def peers_summary(frames: Frames) -> pd.DataFrame:
    """The aggregates of the module docstring, one row per (map, robot count, method)."""
    rows = runs(frames)
    columns = list(DISPLAY) + ["deadlocks", "collisions", "common_instances", "paired", "failed"]
    if rows.empty:
        return pd.DataFrame(columns=columns)
    failed = failures(frames)
    paired = rows.groupby(INSTANCE)["plan_id"].nunique().groupby(["map", "n_robots"]).max() == 1
    baseline = rows[rows["common"] & (rows["method"] == BASELINE)].groupby(["map", "n_robots"])["unnecessary_waiting"].sum()
    out = []
    for (name, n, method), g in rows.groupby(["map", "n_robots", "method"], sort=False):
        common = g[g["common"]]
        tests = g["decisions"].where(g["decisions"] > 0)
        out.append({
            "map": name, "n_robots": int(n), "method": method, "instances": len(g),
            "success_share": float(g["success"].mean()),
            "mean_travel_time": float(common["mean_travel_time"].mean()) if len(common) else float("nan"),
            "unnecessary_waiting": float((common["unnecessary_waiting"] / common["n_robots"]).mean()) if len(common) else float("nan"),
            "waiting_removed": waiting_removed_share(float(common["unnecessary_waiting"].sum()), float(baseline.get((name, n), float("nan"))))
            if len(common) else float("nan"),
            "flips": float(g["flips"].mean()), "decision_ms_per_step": float(1e3 * g["step_decision_seconds"].mean()),
            "decision_ms": float(1e3 * g["decision_seconds"].mean()),
            "switchable": float((g["switchable"] / g["n_obstacles"].where(g["n_obstacles"] > 0)).mean()) if method == "BTPG" else float("nan"),
            "exhausted_share": float((g["budget_exhausted"] / tests).mean()) if method == "optimal" else float("nan"),
            "deadlocks": int(g["deadlock"].sum()), "collisions": int(g["collisions"].sum()), "common_instances": len(common),
            "paired": bool(paired.get((name, n), False)), "failed": int(failed.get((name, n, method), 0)),
        })
    table = pd.DataFrame(out, columns=columns)
    rank = table["method"].map({m: i for i, m in enumerate(METHOD_ORDER)}).fillna(len(METHOD_ORDER))
    maps = table["map"].map({m: i for i, m in enumerate(SWEEPS.values())})
    return table.assign(_m=maps, _r=rank).sort_values(["_m", "n_robots", "_r"]).drop(columns=["_m", "_r"]).reset_index(drop=True)


def tables(frames: Frames) -> dict[str, pd.DataFrame]:
    """``peers``: :func:`peers_summary`."""
    return {"peers": peers_summary(frames)}


def markdown(tables: dict[str, pd.DataFrame]) -> str:
    """The peers table in markdown, with what its columns mean."""
    table = tables["peers"]
    shown = table[list(DISPLAY)].rename(columns=DISPLAY)
    note = ("Travel time, unnecessary waiting and waiting removed over the instances where all five methods finished "
            "without contact; unnecessary waiting = travel time above the delay-only lower bound (each robot alone under "
            "its own disturbances), per robot; waiting removed = 1 − ΣW / ΣW_RMTRACK over those instances; decision time = "
            "flip tests, cycle tests and the optimal method's searches (BTPG's offline classification is not included: "
            "column offline_seconds of the runs).")
    return markdown_table(shown, formats=FORMATS) + "\n\n" + note + "\n"


def figures(tables: dict[str, pd.DataFrame], out: Path) -> list[Path]:
    """``peers.png``: waiting removed and decision time per step against the robot count, per map."""
    return [viz.plot_peers(tables["peers"], Path(out) / "peers.png")]


REPRODUCTION = Reproduction(
    name="coordination-peers",
    family="coordination",
    paper=("label flipping against its peers: BTPG (Su, Veerapaneni & Li, AAAI 2024) and optimal passing orders "
           "(after SADG, Berndt et al., T-RO 2024, and switchable-edge search, Feng et al., ICAPS 2024)"),
    description="Fig. 6 instances and warehouse grids of 50-200 robots: unnecessary waiting removed, travel time, flips, decision time",
    sweeps=tuple(SWEEPS),
    tables=tables,
    markdown=markdown,
    figures=figures,
    budgets={
        "smallest": Budget(seeds=1, grid={"robots.count": [5]}),
        "default": Budget(seeds=3),
        "full": Budget(seeds=10),
    },
    seed_shares={"coordination_peers_grid": 0.34},
)
