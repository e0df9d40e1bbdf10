"""The declared B-UAVC reproductions (``buavc``, ``buavc-models``) at their smallest budget."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from robofleet.core.errors import ConfigError
from robofleet.experiments import deterministic_columns, plan_sweep
from robofleet.experiments.reproduction import reproduce
from robofleet.experiments.reproductions import buavc, buavc_models
from robofleet.experiments.sweep import expand_overrides
from robofleet.scenarios import catalogue, load_scenario


def run_files(directory) -> dict[str, float]:
    """Result-store files of a sweep and their modification times."""
    return {p.name: p.stat().st_mtime_ns for p in directory.glob("*.parquet")}


def reproduce_twice(declaration, out):
    """Run a declaration at the smallest budget, then again into the same directory."""
    first = reproduce(declaration, out=out, budget="smallest", executor="serial", progress=False)
    stored = {sweep: run_files(out / "runs" / sweep) for sweep in declaration.sweeps}
    second = reproduce(declaration, out=out, budget="smallest", executor="serial", progress=False)
    return first, stored, second


def assert_resumed_without_rerun(declaration, first, stored, second, out):
    """The second call rewrote no result file and gave the same rows and tables."""
    for sweep in declaration.sweeps:
        assert run_files(out / "runs" / sweep) == stored[sweep], f"{sweep} ran again"
        a, b = first.frames[sweep], second.frames[sweep]
        pd.testing.assert_frame_equal(a[deterministic_columns(a)], b[deterministic_columns(b)])
    for name, table in first.tables.items():
        pd.testing.assert_frame_equal(table, second.tables[name])


def test_buavc_smallest_budget_writes_runs_tables_figure_and_resumes(tmp_path):
    first, stored, second = reproduce_twice(buavc.REPRODUCTION, tmp_path)
    assert first.failed == 0
    assert {sweep: len(frame) for sweep, frame in first.frames.items()} == {"buavc_noise": 3, "buavc_delta": 1}
    noise, delta = first.tables["noise"], first.tables["delta"]
    assert list(zip(noise["method"], noise["sigma"])) == [("buavc", 0.1), ("bvc", 0.1), ("bvc_inflated", 0.1)]
    assert delta["delta"].tolist() == [0.1] and delta["runs"].tolist() == [1]
    assert ((noise["pair_step_upper"] > noise["pair_step_pooled"]) & (noise["pair_step_upper"] <= 1)).all()
    assert (noise["pair_steps"] == 10 * 21).all()  # 5 robots → 10 pairs, 20 steps → 21 states
    text = (tmp_path / "table.md").read_text()
    lines = text.splitlines()
    for row in ("| buavc | 0.1 | 1 |", "| bvc | 0.1 | 1 |", "| bvc_inflated | 0.1 | 1 |", "| 0.1 | 1 |"):
        assert any(line.startswith(row) for line in lines), row
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert summary["table"].value_counts().to_dict() == {"noise": 3, "delta": 1}
    figure = tmp_path / "buavc_comparison.png"
    assert figure in first.files and figure.stat().st_size > 0
    assert_resumed_without_rerun(buavc.REPRODUCTION, first, stored, second, tmp_path)


def test_buavc_models_smallest_budget_writes_runs_tables_figures_and_resumes(tmp_path):
    first, stored, second = reproduce_twice(buavc_models.REPRODUCTION, tmp_path)
    assert first.failed == 0
    assert sum(len(frame) for frame in first.frames.values()) == 4 + 3 + 3 + 3 + 3 + 3 + 1 + 1
    noise, delta = first.tables["noise"], first.tables["delta"]
    expected = ([("single_integrator", m, 0.1) for m in ("buavc", "bvc", "bvc_inflated", "orca")]
                + [("double_integrator", m, 0.1) for m in ("buavc", "bvc", "bvc_inflated")]
                + [("diff_drive", m, 0.1) for m in ("buavc", "bvc", "bvc_inflated")]
                + [("quadrotor", m, s) for s in (0.05, 0.1) for m in ("buavc", "bvc", "bvc_inflated")]
                + [("heterogeneous", m, 0.04) for m in ("buavc", "bvc", "bvc_inflated")])
    assert list(zip(noise["model"], noise["method"], noise["sigma"])) == expected
    assert list(zip(delta["model"], delta["delta"])) == [("diff_drive", 0.1), ("double_integrator", 0.1)]
    assert (noise["runs"] == 1).all() and noise["unfinished"].between(0, 6).all()
    text = (tmp_path / "table.md").read_text()
    assert "| single_integrator | orca | 0.1 | 1 |" in text and "| quadrotor | buavc | 0.05 | 1 |" in text
    assert any(line.startswith("| double_integrator | 0.1 | 1 |") for line in text.splitlines())
    for name in ("models_noise.png", "models_delta.png"):
        assert (tmp_path / name) in first.files and (tmp_path / name).stat().st_size > 0
    assert_resumed_without_rerun(buavc_models.REPRODUCTION, first, stored, second, tmp_path)


def test_every_sweep_is_a_shipped_name_that_plans_alone():
    """Each sweep file resolves by name and validates every grid point (what
    ``run_sweep(name)`` does before running); the default budgets are the documented
    experiments: 240 + 80 runs for ``buavc``, 404 for ``buavc-models``."""
    counts = {}
    for declaration in (buavc.REPRODUCTION, buavc_models.REPRODUCTION):
        for sweep in declaration.sweeps:
            assert sweep in catalogue.names("sweeps")
            mapping = declaration.sweep_mapping(sweep, declaration.budgets["default"])
            counts[sweep] = len(plan_sweep(mapping).tasks)
            assert len(plan_sweep(sweep).tasks) == counts[sweep], f"{sweep} alone differs from the default budget"
    assert counts["buavc_noise"] == 240 and counts["buavc_delta"] == 80
    assert sum(counts[s] for s in buavc_models.REPRODUCTION.sweeps) == 404


def test_costly_3d_sweeps_run_their_share_of_the_seeds():
    declaration = buavc_models.REPRODUCTION
    default = {s: declaration.sweep_mapping(s, declaration.budgets["default"])["seeds"] for s in declaration.sweeps}
    assert default["buavc_models_quadrotor"] == 2 and default["buavc_models_heterogeneous"] == 4
    assert default["buavc_models_single_integrator"] == 10
    assert declaration.sweep_mapping("buavc_models_heterogeneous", declaration.budgets["smallest"])["seeds"] == 1
    assert declaration.sweep_mapping("buavc_models_heterogeneous", declaration.budgets["default"], seeds=20)["seeds"] == 8


@pytest.mark.parametrize("sweep", ["buavc_models_quadrotor", "buavc_models_heterogeneous"])
def test_3d_sweeps_tie_every_teams_sigma_to_the_boxes(sweep):
    """The 3D sweeps set each team's σ (a list entry) and Σ_o together through one grid key."""
    plan = plan_sweep(sweep)
    key = buavc_models.SIGMA_KEYS[1]
    for combination in plan.combinations:
        spec = load_scenario(plan.scenario, expand_overrides(combination))
        sigma = combination[key]
        assert [team.sigma for team in spec.teams] == [sigma, sigma] and spec.space3d.obstacle_sigma == sigma


def test_clopper_pearson_bound_of_zero_events_has_the_closed_form():
    assert math.isclose(buavc.pooled_upper_bound(0, 1000), 1 - 0.05 ** (1 / 1000), rel_tol=1e-9)
    assert buavc.pooled_upper_bound(5, 5) == 1.0 and math.isnan(buavc.pooled_upper_bound(0, 0))
    assert buavc.pooled_upper_bound(3, 1000) > 3 / 1000


def test_rows_without_the_collision_keys_are_a_one_line_error():
    rows = pd.DataFrame({"run_id": ["a"], "seed": [1], "method": ["buavc"], buavc.SIGMA_KEY: [0.1], "success": [True], "error": [None]})
    frames = {buavc.NOISE_SWEEP: rows, buavc.DELTA_SWEEP: rows.assign(delta=0.1)}
    with pytest.raises(ConfigError, match="buavc_noise: rows: expected the avoidance result keys"):
        buavc.tables(frames)


def test_sweeps_whose_runs_all_failed_give_empty_tables():
    failed = pd.DataFrame({"run_id": ["a"], "seed": [1], "method": ["buavc"], buavc.SIGMA_KEY: [0.1], "delta": [0.1], "error": ["boom"]})
    tables = buavc.tables({buavc.NOISE_SWEEP: failed, buavc.DELTA_SWEEP: failed})
    assert all(len(t) == 0 for t in tables.values()) and "| method | sigma | runs |" in buavc.markdown(tables)
    models = buavc_models.tables({sweep: failed for sweep in buavc_models.REPRODUCTION.sweeps})
    assert all(len(t) == 0 for t in models.values()) and "| model | delta | runs |" in buavc_models.markdown(models)
