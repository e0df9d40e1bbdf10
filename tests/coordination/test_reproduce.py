"""The Fig. 6 reproduction as a declaration, at its smallest budget: six variants on one
instance, paired (same plan, same disturbances), the same rows on every executor."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from robofleet import load_scenario, simulate
from robofleet.cli.main import main
from robofleet.experiments import deterministic_columns, reproduce, run_sweep
from robofleet.experiments.reproductions.rmtrack import REPRODUCTION, SWEEP

ROW_COLUMNS = ["variant", "finished", "deadlock", "n_steps", "flips", "refused_flips", "mean_travel_time", "plan_id"]


@pytest.fixture(scope="module")
def smallest(tmp_path_factory):
    out = tmp_path_factory.mktemp("rmtrack")
    return out, reproduce(REPRODUCTION, out=out, budget="smallest", executor="serial", progress=False)


def test_smallest_budget_writes_tables_and_figures(smallest):
    out, result = smallest
    assert result.failed == 0
    for name in ("summary.csv", "table.md", "fig6.png", "plan.png", "animation.gif"):
        assert (out / name).stat().st_size > 0, name
    assert (out / "example" / "trace.json").exists() and (out / "runs" / SWEEP).is_dir()
    table = result.tables["fig6"]
    assert len(table) == 6 and (table["n_robots"] == 5).all() and np.all(table["finished_share"] <= 1)
    assert table["variant"].tolist()[-1] == "RMTRACK+TFA (checked)" and table["paired"].all()
    text = (out / "table.md").read_text()
    assert text.split("\n\n")[0].count("\n") == 7 and "| 5 | RMTRACK+TFA (checked) | 1 |" in text


def test_six_variants_share_plan_and_disturbances(smallest):
    _, result = smallest
    rows = result.frames[SWEEP]
    assert len(rows) == 6 and rows["error"].isna().all() and rows["seed"].nunique() == 1
    assert rows["plan_id"].nunique() == 1 and rows["n_obstacles"].nunique() == 1  # one plan
    plain = rows[rows["policy.method"] == "rmtrack"]
    # plain RMTRACK never flips, so the check changes nothing: identical runs (same disturbances)
    assert plain["n_steps"].nunique() == 1 and plain["mean_travel_time"].nunique() == 1
    assert (rows["collisions"] == 0).all()
    checked = rows[rows["policy.deadlock_check"]]
    assert checked["finished"].all() and not checked["deadlock"].any()


def test_paired_runs_meet_the_same_disturbances(smallest):
    """Two variants of one seed: wherever a robot stands at the same plan step at the same
    time in both runs, it is disturbed in both or in neither (one stream per robot and step)."""
    _, result = smallest
    seed = int(result.frames[SWEEP]["seed"].iloc[0])
    base = {"robots.count": 5, "robots.instance_seed": None}
    a = simulate(load_scenario("coordination/x_corridor_20", {**base, "policy.method": "rmtrack"}), seed=seed)
    b = simulate(load_scenario("coordination/x_corridor_20", {**base, "policy.method": "tfa"}), seed=seed)
    assert a.results["plan_id"] == b.results["plan_id"]
    t = min(len(a.arrays["disturbed"]), len(b.arrays["disturbed"]))
    same_place = a.arrays["progress"][:t] == b.arrays["progress"][:t]
    assert same_place.sum() > 100
    assert np.array_equal(a.arrays["disturbed"][:t][same_place], b.arrays["disturbed"][:t][same_place])


def test_instances_follow_the_seed_when_instance_seed_is_null():
    spec = load_scenario("coordination/x_corridor_20", {"robots.count": 5, "robots.instance_seed": None, "simulation.max_steps": 3})
    plans = [simulate(spec, seed=s).results["plan_id"] for s in (1, 2, 1)]
    assert plans[0] == plans[2] != plans[1]
    fixed = load_scenario("coordination/x_corridor_5_tff", {"simulation.max_steps": 3})
    assert simulate(fixed, seed=1).results["plan_id"] == simulate(fixed, seed=2).results["plan_id"]


def test_same_rows_whatever_the_executor(tmp_path):
    mapping = REPRODUCTION.sweep_mapping(SWEEP, REPRODUCTION.budgets["smallest"])
    frames = [run_sweep(mapping, executor=kind, workers=1, progress=False, out=tmp_path / kind) for kind in ("serial", "process")]
    serial, process = (f[deterministic_columns(f)].sort_values("run_id").reset_index(drop=True) for f in frames)
    assert set(ROW_COLUMNS) <= set(serial.columns) and len(serial) == 6
    pd.testing.assert_frame_equal(serial, process)


def test_cli_reproduce_writes_table_plots_and_runs(tmp_path, capsys):
    out = tmp_path / "rmtrack"
    main(["reproduce", "rmtrack", "--budget", "smallest", "--executor", "serial", "--out", str(out), "--quiet"])
    assert (out / "fig6.png").stat().st_size > 0 and (out / "summary.csv").exists()
    assert "| 5 | RMTRACK+TFA (checked) | 1 |" in (out / "table.md").read_text()
    with pytest.raises(SystemExit) as bad:
        main(["reproduce", "rmtrack", "--budget", "huge", "--out", str(out)])
    assert bad.value.code == 2 and "--budget" in capsys.readouterr().err
