"""run_tasks: executors agree, results are stored as they finish, sweeps resume."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import textwrap
import time

import pandas as pd
import pyarrow.parquet as pq
import pytest

from robofleet.core.errors import ConfigError
from robofleet.experiments import ResultStore, deterministic_columns, run_tasks
from robofleet.experiments._selftest import noisy_sum
from robofleet.experiments.executors import SeedQueue


def make_tasks(n, **extra):
    return [{"run_id": f"t{i:03d}", "seed": 1000 + i, "n": 3 + i % 4, **extra} for i in range(n)]


def calls(marker_dir) -> int:
    return sum(1 for _ in marker_dir.iterdir())


def comparable(frame: pd.DataFrame) -> pd.DataFrame:
    columns = deterministic_columns(frame)
    return frame[columns].sort_values(["run_id", "part"]).reset_index(drop=True)


def test_rows_are_the_functions_output_merged_with_the_task(tmp_path):
    tasks = make_tasks(3)
    frame = run_tasks(noisy_sum, tasks, tmp_path, executor="serial", progress=False)
    expected = [{**t, **noisy_sum(t)} for t in tasks]
    for row, want in zip(frame.to_dict("records"), expected):
        assert {k: row[k] for k in ("run_id", "seed", "n", "total", "largest")} == {k: want[k] for k in ("run_id", "seed", "n", "total", "largest")}


def test_several_rows_per_task(tmp_path):
    frame = run_tasks(noisy_sum, make_tasks(2, rows=3), tmp_path, executor="serial", progress=False)
    assert frame.groupby("run_id")["part"].apply(list).tolist() == [[0, 1, 2], [0, 1, 2]]


@pytest.fixture(scope="module")
def dask_cluster():
    """A real Dask LocalCluster with 2 worker processes; a task is not retried after it
    killed a worker (``allowed-failures: 0``), which keeps the crash test short."""
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=logging.CRITICAL) as cluster:
            yield cluster


def test_identical_rows_whatever_the_executor(tmp_path, dask_cluster):
    """Serial, local processes and a real Dask LocalCluster (2 worker processes)."""
    tasks = make_tasks(10, rows=2)
    tasks[4]["fail"] = True
    frames = {
        name: run_tasks(noisy_sum, tasks, tmp_path / name, executor=name, workers=2, progress=False,
                        scheduler=dask_cluster.scheduler_address if name == "dask" else None)
        for name in ("serial", "process", "dask")
    }
    reference = comparable(frames["serial"])
    assert len(reference) == 9 * 2 + 1
    for name in ("process", "dask"):
        pd.testing.assert_frame_equal(comparable(frames[name]), reference, check_dtype=True)
    # the timing column exists and is really a timing (it differs between executors)
    assert "compute_seconds" in frames["serial"] and "compute_seconds" not in reference


def test_a_dask_worker_dying_is_recorded_and_the_others_finish(tmp_path, dask_cluster):
    tasks = make_tasks(6)
    tasks[0]["crash"] = True
    frame = run_tasks(noisy_sum, tasks, tmp_path, executor="dask", scheduler=dask_cluster.scheduler_address, progress=False)
    assert sorted(frame["run_id"]) == [t["run_id"] for t in tasks]
    errors = frame.set_index("run_id")["error"]
    assert errors["t000"].startswith("KilledWorker")
    assert errors.isna().sum() >= 3  # the tasks on the surviving worker, at least
    assert "\n" not in errors["t000"]


@pytest.mark.parametrize("executor", ["serial", "process"])
def test_rerun_skips_finished_tasks(tmp_path, executor):
    markers = tmp_path / "calls"
    markers.mkdir()
    tasks = make_tasks(8, marker_dir=str(markers))
    run_tasks(noisy_sum, tasks[:5], tmp_path / "store", executor=executor, workers=2, progress=False)
    assert calls(markers) == 5
    before = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "store").glob("*.parquet")}
    frame = run_tasks(noisy_sum, tasks, tmp_path / "store", executor=executor, workers=2, progress=False)
    assert calls(markers) == 8  # only the three new tasks ran
    assert {p.name: p.stat().st_mtime_ns for p in (tmp_path / "store").glob("*.parquet") if p.name in before} == before
    assert sorted(frame["run_id"]) == [t["run_id"] for t in tasks]
    run_tasks(noisy_sum, tasks, tmp_path / "store", executor=executor, progress=False)
    assert calls(markers) == 8


def test_returns_earlier_rows_too(tmp_path):
    run_tasks(noisy_sum, make_tasks(2), tmp_path, executor="serial", progress=False)
    frame = run_tasks(noisy_sum, [{"run_id": "other", "seed": 1}], tmp_path, executor="serial", progress=False)
    assert sorted(frame["run_id"]) == ["other", "t000", "t001"]


def test_a_failing_task_is_recorded_and_the_others_finish(tmp_path):
    markers = tmp_path / "calls"
    markers.mkdir()
    tasks = make_tasks(6, marker_dir=str(markers))
    tasks[2]["fail"] = True
    frame = run_tasks(noisy_sum, tasks, tmp_path / "store", executor="process", workers=2, progress=False)
    failed = frame[frame["error"].notna()]
    assert failed["run_id"].tolist() == ["t002"]
    assert failed["error"].tolist() == ["ValueError: requested failure of t002"]  # one line
    assert frame["error"].isna().sum() == 5 and frame.loc[frame["error"].isna(), "total"].notna().all()
    # failures are retried on the next run, finished tasks are not
    run_tasks(noisy_sum, tasks, tmp_path / "store", executor="serial", progress=False)
    assert calls(markers) == 7


def test_bad_return_values_become_failure_rows(tmp_path):
    tasks = make_tasks(3)
    outputs = {"t000": 42, "t001": [{"a": 1}, "x"], "t002": {"error": "mine"}}
    frame = run_tasks(lambda task: outputs[task["run_id"]], tasks, tmp_path, executor="serial", progress=False)
    errors = dict(zip(frame["run_id"], frame["error"]))
    assert errors["t000"].startswith("TypeError") and errors["t001"].startswith("TypeError")
    assert "reserved column 'error'" in errors["t002"]


def test_a_crashing_worker_process_does_not_stop_the_others(tmp_path):
    tasks = make_tasks(10)
    tasks[0]["crash"] = True
    frame = run_tasks(noisy_sum, tasks, tmp_path, executor="process", workers=1, progress=False)
    assert sorted(frame["run_id"]) == [t["run_id"] for t in tasks]
    errors = frame.set_index("run_id")["error"]
    assert "BrokenProcessPool" in errors["t000"]
    # tasks submitted after the crash ran on a fresh pool
    assert errors.isna().sum() >= len(tasks) - 4


def test_killed_sweep_loses_only_the_task_in_flight(tmp_path):
    """SIGKILL a sweep mid-way: no partial file; the rerun runs only what was missing."""
    markers = tmp_path / "calls"
    markers.mkdir()
    store = tmp_path / "store"
    script = textwrap.dedent(
        f"""
        from robofleet.experiments import run_tasks
        from robofleet.experiments._selftest import noisy_sum
        tasks = [{{"run_id": f"t{{i:03d}}", "seed": i, "sleep": 0.1, "marker_dir": {str(markers)!r}}} for i in range(30)]
        run_tasks(noisy_sum, tasks, {str(store)!r}, executor="serial", progress=False)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", script])
    deadline = time.monotonic() + 60
    while len(ResultStore(store).finished_ids()) < 4 and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    finished = ResultStore(store).finished_ids()
    started = calls(markers)
    assert 4 <= len(finished) < 30
    assert started - len(finished) <= 1  # serial: at most one task in flight
    for path in store.iterdir():  # every visible file is a complete Parquet file
        if not path.name.startswith("."):
            assert pq.read_table(path).num_rows == 1
    tasks = [{"run_id": f"t{i:03d}", "seed": i, "sleep": 0.0, "marker_dir": str(markers)} for i in range(30)]
    # same run_ids, so the finished ones are skipped whatever the other fields say
    frame = run_tasks(noisy_sum, tasks, store, executor="serial", progress=False)
    assert calls(markers) == started + 30 - len(finished)
    assert len(frame) == 30 and frame["error"].isna().all()
    assert not ResultStore(store).temporary_files()


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"executor": "threads"}, "['serial', 'process', 'dask']"),
        ({"executor": "process", "scheduler": "tcp://x:1"}, "scheduler"),
        ({"executor": "process", "workers": 0}, "workers"),
    ],
)
def test_bad_arguments_raise_config_errors(tmp_path, kwargs, words):
    with pytest.raises(ConfigError, match=words.replace("[", r"\[").replace("]", r"\]")):
        run_tasks(noisy_sum, make_tasks(1), tmp_path, progress=False, **kwargs)


def test_ctrl_c_on_a_process_sweep_keeps_finished_runs_and_records_no_failures(tmp_path):
    """SIGINT to the whole process group (what Ctrl-C does): workers are interrupted too,
    but their interruption is not mistaken for task failures."""
    store = tmp_path / "store"
    script = textwrap.dedent(
        f"""
        import sys
        from robofleet.experiments import run_tasks
        from robofleet.experiments._selftest import noisy_sum
        tasks = [{{"run_id": f"t{{i:03d}}", "seed": i, "sleep": 0.2}} for i in range(60)]
        try:
            run_tasks(noisy_sum, tasks, {str(store)!r}, executor="process", workers=2, progress=False)
        except KeyboardInterrupt:
            sys.exit(130)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
    deadline = time.monotonic() + 60
    while len(ResultStore(store).finished_ids()) < 4 and time.monotonic() < deadline:
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGINT)
    assert proc.wait(timeout=60) == 130
    result = ResultStore(store)
    assert 4 <= len(result.finished_ids()) < 60
    assert result.failed_ids() == set() and result.temporary_files() == []


def test_missing_dask_gives_a_clear_error(tmp_path, monkeypatch):
    from robofleet.core.errors import RobofleetError

    monkeypatch.setitem(sys.modules, "distributed", None)  # makes `import distributed` fail
    with pytest.raises(RobofleetError, match=r"pip install 'robofleet\[dask\]'"):
        run_tasks(noisy_sum, make_tasks(1), tmp_path, executor="dask", progress=False)
    assert not tmp_path.joinpath("run-t000.parquet").exists()


def test_process_executor_rejects_a_function_workers_cannot_import(tmp_path):
    with pytest.raises(ConfigError, match="fn: expected a module-level function"):
        run_tasks(lambda task: {"x": 1}, make_tasks(2), tmp_path, executor="process", progress=False)


def test_ctrl_c_on_the_cli_sweep_exits_130_saying_how_to_resume(tmp_path, robofleet_bin):
    """Ctrl-C on ``robofleet sweep``: exit status 130 and one line with the stored count."""
    sweep = tmp_path / "s.yaml"
    sweep.write_text("scenario: avoidance/ten_boxes\nseeds: 200\n")
    store = tmp_path / "store"
    proc = subprocess.Popen([str(robofleet_bin), "sweep", str(sweep), "--out", str(store), "--workers", "2", "--quiet"],
                            start_new_session=True, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while len(ResultStore(store).finished_ids()) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("interrupted: ") and "of 200 runs stored" in lines[0], err
    assert "rerun the same command to resume" in lines[0] and "Traceback" not in err


def test_process_workers_keep_to_the_seeds_they_claimed_then_take_what_is_left():
    tasks = [{"run_id": f"{variant}-{seed}", "seed": seed} for variant in "abc" for seed in (7, 8, 9)]
    queue = SeedQueue(tasks)
    taken = {0: [], 1: []}
    for worker in (0, 1, 0, 1, 0, 1, 0, 0, 0):  # worker 0 is faster
        taken[worker].append(queue.next_for(worker)["run_id"])
    assert taken[1] == ["a-8", "b-8", "c-8"]  # one seed, in task order, on one worker
    assert taken[0] == ["a-7", "b-7", "c-7", "a-9", "b-9", "c-9"]
    assert not queue and queue.next_for(1) is None


def test_a_worker_with_nothing_left_to_claim_takes_another_workers_seed():
    queue = SeedQueue([{"run_id": str(i), "seed": 1} for i in range(3)])
    assert [queue.next_for(0)["run_id"], queue.next_for(1)["run_id"], queue.next_for(0)["run_id"]] == ["0", "1", "2"]
