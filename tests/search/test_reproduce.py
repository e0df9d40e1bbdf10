"""The Fig. 7 / coverage reproduction, declared: its sweeps, tables and files on a tiny budget."""

from __future__ import annotations

import numpy as np

from robofleet.core.rng import spawn_seeds
from robofleet.experiments import plan_sweep, reproduce, run_sweep
from robofleet.experiments.reproductions.search import (
    REPRODUCTION,
    coverage_markdown,
    coverage_range_summary,
    coverage_summary,
    fig7_markdown,
    fig7_summary,
)


def test_fig7_sweep_covers_the_grid_and_pairs_seeds():
    """4 algorithms × 13 robot counts × 500 seeds = the paper's 26,000 runs; run k has the
    same seed (hence the same starts) at every grid point."""
    plan = plan_sweep("search_fig7")
    assert len(plan.tasks) == 4 * 13 * 500 == 26000
    assert len({t["run_id"] for t in plan.tasks}) == len(plan.tasks)
    assert list(plan.seeds) == spawn_seeds(2017, 500)
    by_point = {}
    for t in plan.tasks:
        by_point.setdefault((t["algorithm"], t["robots.count"]), []).append(t["seed"])
    assert len(by_point) == 52 and all(s == list(plan.seeds) for s in by_point.values())
    assert REPRODUCTION.sweep_mapping("search_fig7", REPRODUCTION.budgets["full"])["seeds"] == 500


def test_tiny_sweep_serial_equals_process(tmp_path):
    mapping = REPRODUCTION.sweep_mapping("search_fig7", REPRODUCTION.budgets["smallest"])
    mapping["grid"]["robots.count"] = [1, 4]
    mapping["seeds"] = 3
    serial = run_sweep(mapping, executor="serial", progress=False, out=tmp_path / "s")
    process = run_sweep(mapping, executor="process", workers=2, progress=False, out=tmp_path / "p")
    assert len(serial) == 4 * 2 * 3
    np.testing.assert_array_equal(serial["search_time"].to_numpy(), process["search_time"].to_numpy())
    assert (serial["run_id"] == process["run_id"]).all()
    summary = fig7_summary(serial)
    assert set(summary["n_robots"]) == {1, 4} and (summary["runs"] == 3).all()
    table = fig7_markdown(summary)
    assert table.count("\n") == 4 and "(1),(2)&(3)" in table
    proposed = serial[serial["algorithm"] == "proposed"]
    assert (proposed["collisions"] == 0).all() and proposed["success"].all()


def test_tiny_coverage_study(tmp_path):
    mapping = REPRODUCTION.sweep_mapping("search_coverage", REPRODUCTION.budgets["smallest"])
    df = run_sweep(mapping, executor="serial", progress=False, out=tmp_path / "c")
    summary = coverage_summary(df)
    assert set(summary["grid"]) == {"triangular", "square", "hexagonal"} and (summary["n_robots"] == 3).all()
    tri = summary[summary["grid"] == "triangular"].iloc[0]
    assert tri["detected_share"] == 1.0 and tri["grid_limit_share"] == 1.0
    assert (summary["detected_share"] <= summary["grid_limit_share"] + 1e-12).all()
    assert "hexagonal" in coverage_markdown(summary)


def test_tiny_coverage_ranges_judge_the_same_routes(tmp_path):
    mapping = REPRODUCTION.sweep_mapping("search_coverage_ranges", REPRODUCTION.budgets["smallest"])
    df = run_sweep(mapping, executor="serial", progress=False, out=tmp_path / "r")
    ranges = coverage_range_summary(df)
    assert list(ranges.columns) == ["grid", "n_robots", "detected_at_rst_0.60a", "detected_at_rst_1.31a"]
    assert (ranges["detected_at_rst_0.60a"] < ranges["detected_at_rst_1.31a"]).all()
    # r_st does not change the routes in situation 2: both ranges judge the same runs
    for _, pair in df.groupby(["grid.kind", "seed"]):
        assert len(pair) == 2 and pair["search_time"].nunique() == 1 and pair["visited_share"].nunique() == 1


def test_reproduce_smallest_writes_every_file(tmp_path):
    result = reproduce(REPRODUCTION, tmp_path / "out", budget="smallest", executor="serial", progress=False)
    names = {p.name for p in result.files}
    assert {"summary.csv", "table.md", "fig7.png", "coverage.png", "fig5_routes.png", "fig6_route.png"} <= names
    assert result.failed == 0 and set(result.tables) == {"fig7", "coverage", "coverage_ranges", "runs"}
    assert "Fig. 7" in result.markdown and "hexagonal" in result.markdown
    again = reproduce(REPRODUCTION, tmp_path / "out", budget="smallest", executor="serial", progress=False)
    assert again.markdown.split("- `search_fig7`")[0] == result.markdown.split("- `search_fig7`")[0]
