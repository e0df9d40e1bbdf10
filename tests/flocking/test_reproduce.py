"""The reproduction pipeline on a tiny budget: tables, plots, executor independence."""

import pandas as pd

from robofleet.experiments import run_tasks
from robofleet.flocking import reproduce


def test_tiny_reproduction_writes_tables(tmp_path, monkeypatch):
    monkeypatch.setattr(reproduce, "COMPARED_PATTERNS", ("wedge",))
    monkeypatch.setattr(reproduce, "COMPARED_ALGORITHMS", ("basic", "hula_hoop"))
    monkeypatch.setattr(reproduce, "SCHEDULERS", ("fsync", "async"))
    out = reproduce.reproduce_flocking(tmp_path, seeds=1, duration=15, executor="serial", progress=False)
    text = (tmp_path / "table.md").read_text()
    assert "## Fig. 11" in text and "## Comparison" in text
    assert list(out["fig11_table"]["pattern"]) == list(reproduce.FIG11_PATTERNS)
    assert len(out["comparison_table"]) == len(reproduce.COMPARED_PATTERNS) * len(reproduce.COMPARED_ALGORITHMS) * len(reproduce.SCHEDULERS)
    from robofleet.viz import flocking as viz
    assert viz.plot_delta_curves(out["curves"], tmp_path / "f11.png").stat().st_size > 0
    assert viz.plot_comparison(out["comparison_table"], tmp_path / "cmp.png").stat().st_size > 0


def test_rows_do_not_depend_on_the_executor(tmp_path):
    tasks = reproduce.comparison_tasks(1, 12.0)[:2]
    a = run_tasks(reproduce.comparison_task, tasks, tmp_path / "serial", executor="serial", progress=False)
    b = run_tasks(reproduce.comparison_task, tasks, tmp_path / "process", executor="process", workers=2, progress=False)
    cols = [c for c in reproduce.SUMMARY_KEYS if c in a]
    pd.testing.assert_frame_equal(a.sort_values("run_id")[cols].reset_index(drop=True), b.sort_values("run_id")[cols].reset_index(drop=True))


def test_animation_and_trace_plot(tmp_path):
    from robofleet.viz import flocking as viz
    trace = reproduce.run_one({"pattern": "line", "duration": 12, "seed": 1})
    assert viz.plot_trace(trace, tmp_path / "t.png").stat().st_size > 0
    gif = viz.animate_trace(trace, tmp_path / "a.gif", max_frames=5)
    assert gif.stat().st_size > 0
