"""The Fig. 6 reproduction on a tiny scale: one task, six variants on one instance."""

from __future__ import annotations

import numpy as np
import pandas as pd

from robofleet.coordination.reproduce import make_tasks, markdown_table, run_instance, summarize
from robofleet.experiments import run_tasks


def test_six_variants_share_plan_and_disturbances(tmp_path):
    tasks = make_tasks([5], instances=1, root_seed=3)
    rows = run_tasks(run_instance, tasks, tmp_path / "runs", executor="serial", progress=False)
    assert len(rows) == 6 and rows["error"].isna().all()
    assert rows["n_obstacles"].nunique() == 1 and rows["plan_seconds"].nunique() == 1
    plain = rows[rows["method"] == "rmtrack"]
    # plain RMTRACK never flips, so the check changes nothing: identical runs
    assert plain["steps"].nunique() == 1 and plain["mean_travel_time"].nunique() == 1
    assert (rows["collisions"] == 0).all()
    checked = rows[rows["deadlock_check"]]
    assert checked["finished"].all() and not checked["deadlock"].any()
    again = pd.DataFrame(run_instance(tasks[0]))  # a rerun gives the same rows (timings aside)
    cols = ["variant", "finished", "deadlock", "steps", "flips", "refused_flips", "mean_travel_time"]
    by_variant = lambda f: f.sort_values("variant")[cols].reset_index(drop=True)  # noqa: E731
    pd.testing.assert_frame_equal(by_variant(again), by_variant(rows), check_dtype=False)
    summary = summarize(rows)
    assert len(summary) == 6 and np.all(summary["finished_share"] <= 1)
    table = markdown_table(summary)
    assert table.count("\n") == 8 and "RMTRACK+TFA (checked)" in table


def test_same_rows_whatever_the_executor(tmp_path):
    tasks = make_tasks([5], instances=1, root_seed=5)
    cols = ["variant", "finished", "deadlock", "steps", "flips", "refused_flips", "mean_travel_time"]
    frames = [run_tasks(run_instance, tasks, tmp_path / kind, executor=kind, workers=1, progress=False)
              for kind in ("serial", "process")]
    serial, process = (f.sort_values("variant")[cols].reset_index(drop=True) for f in frames)
    pd.testing.assert_frame_equal(serial, process)


def test_cli_reproduce_writes_table_plots_and_runs(tmp_path):
    from typer.testing import CliRunner

    from robofleet.cli.main import app

    out = tmp_path / "rmtrack"
    result = CliRunner().invoke(app, ["reproduce", "rmtrack", "--instances", "1", "--robots", "5", "--executor", "serial",
                                      "--no-animate", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert (out / "fig6.png").stat().st_size > 0 and (out / "summary.csv").exists()
    assert "| 5 | RMTRACK+TFA (checked) | 1 |" in (out / "table.md").read_text()
    bad = CliRunner().invoke(app, ["reproduce", "rmtrack", "--robots", "five", "--out", str(out)])
    assert bad.exit_code != 0
