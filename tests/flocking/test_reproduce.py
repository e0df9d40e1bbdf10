"""The flocking reproduction as a declaration, at its smallest budget: tables, figures,
resuming, executor independence; and the trace figures."""

import pandas as pd
import pytest

import robofleet
from robofleet.core.errors import ConfigError
from robofleet.experiments import deterministic_columns, reproduce, run_sweep
from robofleet.experiments.reproductions import flocking as declaration
from robofleet.experiments.reproductions.flocking import REPRODUCTION


@pytest.fixture(scope="module")
def smallest(tmp_path_factory):
    out = tmp_path_factory.mktemp("flocking_reproduction")
    return out, reproduce(REPRODUCTION, out=out, budget="smallest", executor="serial", progress=False)


def test_smallest_reproduction_writes_tables_and_figures(smallest):
    out, result = smallest
    text = (out / "table.md").read_text()
    assert "## Fig. 11" in text and "## Comparison" in text and result.markdown == text
    assert result.failed == 0
    assert list(result.tables["fig11"]["pattern"]) == list(declaration.FIG11_PATTERNS)
    comparison = result.tables["comparison"]
    assert len(comparison) == 2 * 2 * 2   # wedge, spread × fsync, async × basic, hula_hoop at the smallest budget
    assert list(comparison["scheduler"].unique()) == ["fsync", "async"]
    assert set(pd.read_csv(out / "summary.csv")["table"]) == {"fig11", "comparison", "fig11_runs"}
    for name in ("fig11_delta.png", "comparison.png", "fig9_wedge.png", "fig9_wedge.gif", "fig10_spread.png", "fig10_spread.gif"):
        assert (out / name).stat().st_size > 0, name
    assert robofleet.Trace.load(out / "fig9_wedge_trace").metadata["n_steps"] == 15


def test_a_second_run_resumes_from_the_stores(smallest):
    out, first = smallest
    again = reproduce(REPRODUCTION, out=out, budget="smallest", executor="serial", progress=False)
    pd.testing.assert_frame_equal(first.tables["comparison"], again.tables["comparison"])
    assert again.markdown == first.markdown


def test_fig11_curves_are_the_runs_of_the_table(smallest):
    _, result = smallest
    runs = result.tables["fig11_runs"]
    curves = declaration.delta_curves(runs)
    assert set(curves["run_id"]) == set(runs["run_id"])
    wrong = runs.assign(delta_e_final=runs["delta_e_final"] + 1.0)
    with pytest.raises(ConfigError, match="expected the re-simulated run"):
        declaration.delta_curves(wrong.iloc[:1])


def test_rows_do_not_depend_on_the_executor(tmp_path):
    mapping = REPRODUCTION.sweep_mapping(declaration.COMPARISON_SWEEP, REPRODUCTION.budgets["smallest"])
    mapping["grid"].update({"pattern.kind": ["wedge"], "algorithm.kind": ["hula_hoop"]})
    a = run_sweep(mapping, executor="serial", progress=False, out=tmp_path / "serial")
    b = run_sweep(mapping, executor="process", workers=1, progress=False, out=tmp_path / "process")
    cols = deterministic_columns(a)
    pd.testing.assert_frame_equal(a[cols].reset_index(drop=True), b[cols].reset_index(drop=True))


def test_animation_and_trace_plot(tmp_path):
    from robofleet.viz import flocking as viz
    spec = robofleet.load_scenario("flocking/wedge_async", overrides={"pattern.kind": "line", "duration": 12})
    trace = robofleet.simulate(spec, seed=1)
    assert viz.plot_trace(trace, tmp_path / "t.png").stat().st_size > 0
    gif = viz.animate_trace(trace, tmp_path / "a.gif", max_frames=5)
    assert gif.stat().st_size > 0
