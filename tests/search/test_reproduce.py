"""The Fig. 7 / coverage reproduction on a tiny budget, through the shared run_tasks."""

from __future__ import annotations

import numpy as np

from robofleet.experiments import run_tasks
from robofleet.search.reproduce import (coverage_markdown, coverage_summary, coverage_task, coverage_tasks, fig7_markdown,
                                        fig7_summary, fig7_task, fig7_tasks)


def test_fig7_tasks_cover_the_grid_and_pair_seeds():
    tasks = fig7_tasks(runs=10, batch=4)
    assert len(tasks) == 4 * 13 * 3
    assert len({t["run_id"] for t in tasks}) == len(tasks)
    assert sum(t["n_runs"] for t in tasks) == 4 * 13 * 10


def test_tiny_sweep_serial_equals_process(tmp_path):
    tasks = fig7_tasks(runs=3, batch=2, robots=(1, 4))
    serial = run_tasks(fig7_task, tasks, tmp_path / "s", executor="serial", progress=False)
    process = run_tasks(fig7_task, tasks, tmp_path / "p", executor="process", workers=2, progress=False)
    assert len(serial) == 4 * 2 * 3
    key = ["algorithm", "n_robots", "run_index"]
    a, b = serial.sort_values(key).reset_index(drop=True), process.sort_values(key).reset_index(drop=True)
    np.testing.assert_array_equal(a["search_time"].to_numpy(), b["search_time"].to_numpy())
    summary = fig7_summary(serial)
    assert set(summary["n_robots"]) == {1, 4} and (summary["runs"] == 3).all()
    table = fig7_markdown(summary)
    assert table.count("\n") == 4 and "(1),(2)&(3)" in table
    assert (serial[serial["algorithm"] == "proposed"]["collisions"] == 0).all()


def test_tiny_coverage_study(tmp_path):
    tasks = coverage_tasks(runs=2, batch=2, robots=(3,))
    df = run_tasks(coverage_task, tasks, tmp_path / "c", executor="serial", progress=False)
    summary = coverage_summary(df)
    assert set(summary["grid"]) == {"triangular", "square", "hexagonal"}
    tri = summary[summary["grid"] == "triangular"].iloc[0]
    assert tri["detected_share"] == 1.0 and tri["grid_limit_share"] == 1.0
    assert (summary["detected_share"] <= summary["grid_limit_share"] + 1e-12).all()
    assert "hexagonal" in coverage_markdown(summary)
