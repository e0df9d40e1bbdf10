"""Sweeps: validation of the sweep file, task expansion, stable run ids, end to end."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pandas as pd
import pytest
import yaml

from robofleet.core.errors import ScenarioError
from robofleet.core.rng import spawn_seeds
from robofleet.experiments import deterministic_columns, plan_sweep, run_sweep, summarize_sweep
from robofleet.experiments.sweep import stable_run_id

SCENARIO = {"family": "toy", "robots": {"n": 3, "radius": 0.2}, "noise": {"sigma": 0.05}, "steps": 15}


def write_sweep(tmp_path, name="sweep.yaml", **sweep):
    (tmp_path / "toy.yaml").write_text(yaml.safe_dump(SCENARIO))
    doc = {"scenario": "toy.yaml", "grid": {"noise.sigma": [0.0, 0.3], "robots.n": [2, 4]}, "seeds": 3, "out": str(tmp_path / "out")}
    doc.update(sweep)
    doc = {k: v for k, v in doc.items() if v is not None}
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_tasks_are_grid_product_times_seeds(tmp_path, toy_family):
    plan = plan_sweep(write_sweep(tmp_path, root_seed=7))
    assert plan.grid_keys == ("noise.sigma", "robots.n")
    assert plan.seeds == tuple(spawn_seeds(7, 3))
    expected = [(s, n, seed) for s, n in itertools.product([0.0, 0.3], [2, 4]) for seed in plan.seeds]
    assert [(t["noise.sigma"], t["robots.n"], t["seed"]) for t in plan.tasks] == expected
    assert len({t["run_id"] for t in plan.tasks}) == 12


def test_explicit_seed_list_and_empty_grid(tmp_path, toy_family):
    plan = plan_sweep(write_sweep(tmp_path, grid={}, seeds=[5, 1, 9]))
    assert [t["seed"] for t in plan.tasks] == [5, 1, 9] and plan.grid_keys == ()


def test_run_ids_are_stable_and_depend_on_scenario_parameters_and_seed(tmp_path, toy_family):
    first = plan_sweep(write_sweep(tmp_path))
    again = plan_sweep(write_sweep(tmp_path / ".." / tmp_path.name, name="copy.yaml"))
    assert [t["run_id"] for t in first.tasks] == [t["run_id"] for t in again.tasks]
    assert stable_run_id(SCENARIO, {"a": 1}, 3) == stable_run_id(dict(reversed(SCENARIO.items())), {"a": 1}, 3)
    assert stable_run_id(SCENARIO, {"a": 1}, 3) != stable_run_id(SCENARIO, {"a": 2}, 3)
    assert stable_run_id(SCENARIO, {"a": 1}, 3) != stable_run_id(SCENARIO, {"a": 1}, 4)
    assert stable_run_id(SCENARIO, {"a": 1}, 3) != stable_run_id({**SCENARIO, "steps": 16}, {"a": 1}, 3)


def test_end_to_end_rows_summary_and_resume(tmp_path, toy_family):
    path = write_sweep(tmp_path)
    frame = run_sweep(path, executor="serial", progress=False)
    plan = plan_sweep(path)
    assert frame["run_id"].tolist() == [t["run_id"] for t in plan.tasks]
    assert frame.attrs["grid"] == ["noise.sigma", "robots.n"] and frame.attrs["store"] == str(tmp_path / "out")
    assert frame["error"].isna().all()
    # each row is the run's own summary, replayable from its seed
    row = frame.iloc[7]
    from robofleet import load_scenario, simulate

    spec = load_scenario(tmp_path / "toy.yaml", overrides={"noise.sigma": row["noise.sigma"], "robots.n": int(row["robots.n"])})
    replay = simulate(spec, seed=int(row["seed"])).summary()
    assert replay["final_spread"] == row["final_spread"] and replay["n_robots"] == row["robots.n"]
    # re-running writes nothing new
    before = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "out").glob("*.parquet")}
    again = run_sweep(path, executor="serial", progress=False)
    assert {p.name: p.stat().st_mtime_ns for p in (tmp_path / "out").glob("*.parquet")} == before
    pd.testing.assert_frame_equal(again, frame)


def test_same_rows_with_processes_as_serially(tmp_path, toy_family):
    path = write_sweep(tmp_path)
    serial = run_sweep(path, executor="serial", progress=False, out=tmp_path / "serial")
    process = run_sweep(path, executor="process", workers=2, progress=False, out=tmp_path / "process")
    columns = deterministic_columns(serial)
    assert "median_step_seconds" not in columns and "makespan" in columns
    pd.testing.assert_frame_equal(serial[columns], process[columns])


def test_metrics_keep_only_the_listed_summary_keys(tmp_path, toy_family):
    frame = run_sweep(write_sweep(tmp_path, metrics=["success", "final_spread"]), executor="serial", progress=False)
    assert set(frame.columns) == {"run_id", "seed", "noise.sigma", "robots.n", "success", "final_spread", "error"}


@pytest.mark.parametrize("metrics, named", [(["nope"], "'nope'"), (["success", "nope", "final_spred"], "['nope', 'final_spred']")])
def test_a_metric_no_summary_has_is_refused_in_one_line_before_anything_runs(tmp_path, toy_family, metrics, named):
    path = write_sweep(tmp_path, metrics=metrics, seeds=1)
    with pytest.raises(ScenarioError) as info:
        run_sweep(path, executor="serial", progress=False)
    message = str(info.value)
    assert message.startswith(f"{path}: metrics: expected summary keys of toy runs (family, scenario, seed, success, ")
    assert "final_spread" in message and message.endswith(f"received {named}") and "\n" not in message
    assert not (tmp_path / "out").exists()


def test_the_cli_refuses_a_sweep_metric_no_summary_has(tmp_path, capsys):
    from robofleet.cli.main import main

    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"scenario": "search/fig7", "seeds": 1, "metrics": ["search_time", "successs"]}))
    for command in ("validate", "sweep"):
        with pytest.raises(SystemExit) as info:
            main([command, str(path)])
        lines = capsys.readouterr().err.strip().splitlines()
        assert info.value.code == 2 and len(lines) == 1 and lines[0].startswith(f"error: {path}: metrics: expected summary keys of search runs")
        assert lines[0].endswith("received 'successs'"), lines


def test_a_metric_some_runs_lack_is_empty_in_their_rows(tmp_path):
    sweep = {"scenario": "flocking/wedge_async", "overrides": {"duration": 3.0}, "seeds": 1, "out": str(tmp_path / "out"),
             "metrics": ["success", "delta_m_final"]}  # the wedge is lb-symmetric: its runs have no mirror-image keys
    frame = run_sweep(sweep, executor="serial", progress=False)
    assert frame["error"].isna().all() and frame["delta_m_final"].isna().all() and len(frame) == 1


def test_inline_scenario_and_default_out(tmp_path, toy_family, monkeypatch):
    monkeypatch.chdir(tmp_path)
    frame = run_sweep({"scenario": SCENARIO, "grid": {"steps": [3]}, "seeds": 2}, executor="serial", progress=False)
    assert frame.attrs["store"] == "results/sweep" and (tmp_path / "results" / "sweep").is_dir()
    path = write_sweep(tmp_path, name="mine.yaml", out=None, seeds=1)
    assert plan_sweep(path).out.as_posix() == "results/mine"


def test_summary_means_per_combination(tmp_path, toy_family):
    frame = run_sweep(write_sweep(tmp_path), executor="serial", progress=False)
    means = summarize_sweep(frame)
    assert means[["noise.sigma", "robots.n"]].values.tolist() == [[0.0, 2], [0.0, 4], [0.3, 2], [0.3, 4]]
    assert means["runs"].tolist() == [3, 3, 3, 3] and means["failed"].tolist() == [0, 0, 0, 0]
    for _, row in means.iterrows():
        group = frame[(frame["noise.sigma"] == row["noise.sigma"]) & (frame["robots.n"] == row["robots.n"])]
        assert row["final_spread"] == pytest.approx(group["final_spread"].mean())
        assert row["success"] == pytest.approx(group["success"].astype(float).mean())
    assert "seed" not in means and "run_id" not in means


@pytest.mark.parametrize(
    "change, field",
    [
        ({"colour": "red"}, "colour"),
        ({"scenario": 3}, "scenario"),
        ({"grid": [1, 2]}, "grid"),
        ({"grid": {"noise.sigma": []}}, "grid.noise.sigma"),
        ({"grid": {"noise.sigma": 0.1}}, "grid.noise.sigma"),
        ({"grid": {"seed": [1]}}, "grid.seed"),
        ({"grid": {"a..b": [1]}}, "grid"),
        ({"seeds": 0}, "seeds"),
        ({"seeds": -2}, "seeds"),
        ({"seeds": []}, "seeds"),
        ({"seeds": [1, "2"]}, "seeds"),
        ({"seeds": [1, 1]}, "seeds"),
        ({"seeds": True}, "seeds"),
        ({"root_seed": -1}, "root_seed"),
        ({"metrics": []}, "metrics"),
        ({"out": 5}, "out"),
    ],
)
def test_invalid_sweep_files_name_file_and_field(tmp_path, toy_family, change, field):
    path = write_sweep(tmp_path, **change)
    with pytest.raises(ScenarioError) as info:
        plan_sweep(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {field}") and "\n" not in message and "expected" in message


def test_missing_seeds_is_an_error(tmp_path, toy_family):
    path = write_sweep(tmp_path)
    doc = yaml.safe_load(path.read_text())
    del doc["seeds"]
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ScenarioError, match="seeds: expected this required field"):
        plan_sweep(path)


def test_grid_value_invalidating_the_scenario_is_caught_before_running(tmp_path, toy_family):
    path = write_sweep(tmp_path, grid={"robots.radius": [0.1, -1.0]})
    with pytest.raises(ScenarioError) as info:
        run_sweep(path, executor="serial", progress=False)
    message = str(info.value)
    assert message.startswith(f"{path}: grid robots.radius=-1.0 → {tmp_path / 'toy.yaml'}: robots.radius: expected")
    assert not (tmp_path / "out").exists()


def test_grid_path_not_in_the_scenario_is_caught(tmp_path, toy_family):
    path = write_sweep(tmp_path, grid={"robots.colour": ["red"]})
    with pytest.raises(ScenarioError, match=r"grid robots.colour='red' → .*toy.yaml: robots.colour: expected no such key"):
        plan_sweep(path)


def test_missing_scenario_file_is_named(tmp_path, toy_family):
    path = write_sweep(tmp_path, scenario="absent.yaml", grid={})
    with pytest.raises(ScenarioError, match=r"sweep.yaml: scenario → .*absent.yaml: expected a readable YAML file"):
        plan_sweep(path)


def test_parameter_columns_hold_validated_values(tmp_path, toy_family):
    """YAML reads 1e-1 as a string; the float field makes it 0.1, and so does the column."""
    path = tmp_path / "s.yaml"
    (tmp_path / "toy.yaml").write_text(yaml.safe_dump(SCENARIO))
    path.write_text("scenario: toy.yaml\ngrid:\n  noise.sigma: [1e-1]\n  robots: [{n: 2}, {n: 3, radius: 0.3}]\nseeds: 1\n")
    plan = plan_sweep(path)
    assert [t["noise.sigma"] for t in plan.tasks] == [0.1, 0.1]
    assert plan.tasks[1]["robots"] == {"n": 3, "radius": 0.3}
    frame = run_sweep(path, executor="serial", progress=False, out=tmp_path / "o")
    assert frame["noise.sigma"].tolist() == [0.1, 0.1]
    assert [json.loads(v) for v in frame["robots"]] == [{"n": 2, "radius": 0.1}, {"n": 3, "radius": 0.3}]
    assert frame["n_robots"].tolist() == [2, 3]
    assert summarize_sweep(frame)["runs"].tolist() == [1, 1]


def test_the_scenario_file_is_read_once_and_each_grid_point_validated_once(tmp_path, toy_family, monkeypatch):
    """A sweep of 2 grid points × 5 seeds reads its scenario file once and validates each
    point once (while planning); its 10 runs reuse those specs."""
    from robofleet import load_scenario
    from robofleet.core import config
    from robofleet.experiments import sweep as sweep_module

    sweep_module._specs.clear()
    path = write_sweep(tmp_path, grid={"robots.n": [2, 4]}, seeds=5)
    reads, validations = [], []
    read_mapping, spec_from_data = config.read_mapping, sweep_module.spec_from_data
    monkeypatch.setattr(config, "read_mapping", lambda ref: reads.append(ref) or read_mapping(ref))
    monkeypatch.setattr(sweep_module, "spec_from_data", lambda *a: validations.append(a[2]) or spec_from_data(*a))
    frame = run_sweep(path, executor="serial", progress=False)
    assert len(frame) == 10 and frame["error"].isna().all()
    assert [str(r) for r in reads if not isinstance(r, dict)].count(str(tmp_path / "toy.yaml")) == 1
    assert validations == [str(tmp_path / "toy.yaml")] * 2
    for n in (2, 4):  # the cached spec is the one load_scenario gives, file included
        spec = sweep_module.sweep_spec(*(plan_sweep(path).fn.keywords[k] for k in ("scenario", "source", "digest")), {"robots.n": n})
        reference = load_scenario(tmp_path / "toy.yaml", overrides={"robots.n": n})
        assert spec == reference and spec.source == reference.source


def test_an_edited_scenario_file_is_validated_anew(tmp_path, toy_family):
    """Specs are cached by the scenario's content: an edit between two sweeps in one process is seen."""
    path = write_sweep(tmp_path, grid={}, seeds=2)
    first = run_sweep(path, executor="serial", progress=False, out=tmp_path / "a")
    (tmp_path / "toy.yaml").write_text(yaml.safe_dump({**SCENARIO, "steps": 2}))
    second = run_sweep(path, executor="serial", progress=False, out=tmp_path / "a")
    assert set(first["run_id"]).isdisjoint(second["run_id"])
    from robofleet import load_scenario, simulate

    replay = simulate(load_scenario(tmp_path / "toy.yaml"), seed=int(second["seed"][0])).summary()
    assert second["final_spread"][0] == replay["final_spread"] != first["final_spread"][0]


def test_run_ids_hashed_per_grid_point_are_the_stable_run_ids():
    from robofleet.experiments.sweep import run_ids

    rng = np.random.default_rng(4)
    for _ in range(30):
        scenario = {"family": "toy", "steps": int(rng.integers(1, 99)), "robots": {"n": int(rng.integers(1, 9))}, "x": [1.5, None, "é"]}
        parameters = {"noise.sigma": float(rng.random()), "robots": {"n": 3}, "a+b": "text"}
        seeds = tuple(int(s) for s in rng.integers(0, 2**63, size=5, dtype=np.uint64))
        assert run_ids(scenario, parameters, seeds) == [stable_run_id(scenario, parameters, seed) for seed in seeds]
