"""The B-UAVC reproduction pipeline on a tiny plan (serial executor)."""

import robofleet.avoidance.reproduce as rep


def test_reproduction_rows_tables_and_resume(tmp_path):
    from robofleet.experiments import run_tasks

    tasks = [t for t in rep.plan(1, sigmas=(0.1,), deltas=(0.1,)) if t["method"] in ("buavc", "bvc")]
    frame = run_tasks(rep.run_one, tasks, tmp_path / "runs", executor="serial", progress=False)
    assert len(frame) == len(tasks) and frame["error"].isna().all()
    assert {"pair_step_rate", "pair_rate", "run_collided", "success"} <= set(frame.columns)
    assert (frame["pair_step_rate"] <= 1).all()
    noise, delta = rep.tables(frame)
    text = rep.markdown(noise, delta)
    assert "| buavc | 0.1 | 1 |" in text
    again = run_tasks(rep.run_one, tasks, tmp_path / "runs", executor="serial", progress=False)
    assert again.drop(columns=[c for c in again.columns if "seconds" in c]).equals(frame.drop(columns=[c for c in frame.columns if "seconds" in c]))
