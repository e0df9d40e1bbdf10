"""Batched result stores: many tasks per file, the journal, kill and resume, earlier
stores, every executor (custom concurrent.futures executors included) giving the same table."""

from __future__ import annotations

import concurrent.futures
import json
import logging
import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from robofleet.core.errors import ConfigError
from robofleet.experiments import ResultStore, deterministic_columns, run_tasks
from robofleet.experiments._selftest import noisy_sum
from robofleet.experiments.executors import ChunkSizer, MAX_CHUNK, call_chunk
from robofleet.experiments.store import (BATCH_PREFIX, FORMAT, JOURNAL_PREFIX, META_FORMAT, Record, StoreFormatError,
                                         rows_to_table)


def varied_tasks(n, seed=0, failures=True, **extra):
    """Tasks whose results differ in shape: several rows, failures, extra fields."""
    rng = np.random.default_rng(seed)
    tasks = []
    for i in range(n):
        task = {"run_id": f"t{i:04d}", "seed": 100 + i, "n": int(rng.integers(1, 6)), **extra}
        if rng.random() < 0.2:
            task["rows"] = int(rng.integers(0, 3))  # 0 rows: a finished task without rows
        if rng.random() < 0.1 and failures:
            task["fail"] = True
        if rng.random() < 0.1:
            task["label"] = "extra field"
        tasks.append(task)
    return tasks


def table(frame: pd.DataFrame) -> pd.DataFrame:
    """The deterministic part of a store's table (timings left out), in store order."""
    return frame[deterministic_columns(frame)].reset_index(drop=True)


def store_files(directory):
    return sorted(p.name for p in directory.iterdir() if not p.name.startswith("."))


def test_tasks_are_written_many_per_file_and_read_back_in_run_id_order(tmp_path):
    tasks = varied_tasks(200)
    frame = run_tasks(noisy_sum, tasks, tmp_path, executor="serial", progress=False)
    assert store_files(tmp_path) == [f"{BATCH_PREFIX}000001.parquet"]
    assert not list(tmp_path.glob(f"{JOURNAL_PREFIX}*"))
    finished = [t for t in tasks if not t.get("fail")]
    assert ResultStore(tmp_path).finished_ids() == {t["run_id"] for t in finished}
    assert ResultStore(tmp_path).failed_ids() == {t["run_id"] for t in tasks if t.get("fail")}
    expected_rows = sum(1 if t.get("fail") else t.get("rows", 1) for t in tasks)
    assert any(t.get("rows") == 0 for t in finished)
    assert len(frame) == expected_rows and frame["run_id"].is_monotonic_increasing
    assert len(pd.read_parquet(tmp_path)) == expected_rows  # any Parquet reader sees the same rows


def test_a_store_without_failures_still_has_the_error_column_for_any_reader(tmp_path):
    polars = pytest.importorskip("polars")
    run_tasks(noisy_sum, varied_tasks(20, seed=3, failures=False), tmp_path, executor="serial", progress=False)
    raw = pd.read_parquet(tmp_path)
    assert "error" in raw.columns and raw["error"].isna().all()
    assert raw[raw["error"].isna()].shape[0] == len(raw)  # the filter the docs show
    assert "error" in polars.read_parquet(str(tmp_path / "*.parquet")).columns
    assert ResultStore(tmp_path).read()["error"].isna().all()


KILLER = textwrap.dedent(
    """
    import sys
    from robofleet.experiments import store, run_tasks
    from robofleet.experiments._selftest import noisy_sum
    sys.path.insert(0, {tests!r})
    from test_experiments_batches import varied_tasks
    store.BATCH_SECONDS = 0.3  # several batch files before the kill
    tasks = varied_tasks({n}, marker_dir={markers!r}, sleep=0.004)
    run_tasks(noisy_sum, tasks, {store_dir!r}, executor={executor!r}, workers=2, progress=False)
    """
)


def kill_part_way(tmp_path, store_dir, markers, n, stop_after, executor):
    """Start a sweep in another process group, SIGKILL it (and its workers) once the store
    holds ``stop_after`` finished tasks."""
    script = KILLER.format(tests=os.path.dirname(__file__), n=n, markers=str(markers), store_dir=str(store_dir), executor=executor)
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
    deadline = time.monotonic() + 600

    def mid_batch() -> bool:
        journals = list(store_dir.glob(f"{JOURNAL_PREFIX}*")) if store_dir.is_dir() else []
        return len(ResultStore(store_dir).finished_ids()) >= stop_after and any(p.stat().st_size for p in journals)

    while not mid_batch() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.005)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


@pytest.mark.parametrize("executor, stops", [("serial", (37, 120)), ("process", (25, 140))])
def test_a_sweep_killed_mid_batch_resumes_exactly_and_ends_with_the_uninterrupted_table(tmp_path, executor, stops):
    """SIGKILL twice part way (batches written, a journal open), then resume: every task
    stored before a kill is skipped, every other one runs, and the table is the table
    of a run that was never interrupted (same rows, columns, order and types)."""
    n = 220
    markers = tmp_path / "calls"
    markers.mkdir()
    store_dir = tmp_path / "killed"
    for stop_after in stops:  # killed while a batch is being collected (its journal holds runs)
        kill_part_way(tmp_path, store_dir, markers, n, stop_after, executor)
    stored = ResultStore(store_dir).finished_ids()
    assert len(stored) >= stops[-1] and len(stored) < n
    started = sum(1 for _ in markers.iterdir())
    tasks = varied_tasks(n, marker_dir=str(markers), sleep=0.004)
    resumed = run_tasks(noisy_sum, tasks, store_dir, executor="serial", progress=False)
    ran_again = sum(1 for _ in markers.iterdir()) - started
    failed_before = ResultStore(store_dir).failed_ids() & stored
    assert not failed_before
    assert ran_again == n - len(stored)  # exactly the tasks not stored
    assert not any(p.name.startswith(".") and p.name != ".writer.lock" for p in store_dir.iterdir())
    whole = run_tasks(noisy_sum, tasks, tmp_path / "whole", executor="serial", progress=False)
    pd.testing.assert_frame_equal(table(resumed), table(whole))
    pd.testing.assert_frame_equal(table(pd.read_parquet(store_dir).sort_values("run_id", kind="stable")),
                                  table(pd.read_parquet(tmp_path / "whole").sort_values("run_id", kind="stable")))


def test_a_journal_line_cut_short_by_a_kill_is_left_out_and_its_task_redone(tmp_path):
    records = [Record.of({"run_id": f"r{i}", "seed": i}, "ok", [{"x": float(i)}]) for i in range(3)]
    text = "".join(r.line() for r in records)
    (tmp_path / f"{JOURNAL_PREFIX}000001.jsonl").write_text(text[:-7])  # the last line cut short
    store = ResultStore(tmp_path)
    assert store.finished_ids() == {"r0", "r1"}
    assert store.read()["run_id"].tolist() == ["r0", "r1"]
    frame = run_tasks(noisy_sum, [{"run_id": f"r{i}", "seed": i} for i in range(3)], tmp_path, executor="serial", progress=False)
    assert frame["x"].tolist()[:2] == [0.0, 1.0] and frame["run_id"].tolist() == ["r0", "r1", "r2"]
    assert store_files(tmp_path) == ["batch-000001.parquet", "batch-000002.parquet"]


def test_a_kill_between_writing_a_batch_and_dropping_its_journal_loses_and_doubles_nothing(tmp_path):
    tasks = [{"run_id": f"r{i}", "seed": i} for i in range(4)]
    run_tasks(noisy_sum, tasks, tmp_path, executor="serial", progress=False)
    journal = tmp_path / f"{JOURNAL_PREFIX}000001.jsonl"
    records = [Record.of(t, *("ok", [noisy_sum(t)])) for t in tasks]
    journal.write_text("".join(r.line() for r in records))  # as if killed just before the unlink
    store = ResultStore(tmp_path)
    assert len(store.read()) == 4 and store.finished_ids() == {t["run_id"] for t in tasks}
    run_tasks(noisy_sum, tasks, tmp_path, executor="serial", progress=False)
    assert not journal.exists() and store_files(tmp_path) == ["batch-000001.parquet"]


def write_format_1_store(directory, tasks):
    """A store as format 1 wrote it: one file per task, ``error-`` files for failures, no
    ``error`` column in the files of finished tasks, no metadata."""
    directory.mkdir()
    for task in tasks:
        from urllib.parse import quote

        stem = quote(task["run_id"], safe="")
        if task.get("fail"):
            pq.write_table(rows_to_table([{**task, "error": "ValueError: an earlier failure"}]), directory / f"error-{stem}.parquet")
        else:
            rows = noisy_sum(task)
            rows = rows if isinstance(rows, list) else [rows]
            merged = [{**task, **{k: v for k, v in row.items() if k not in task}} for row in rows]
            pq.write_table(rows_to_table(merged) if merged else pa.table({k: pa.array([], type=pa.array([v]).type) for k, v in task.items()}),
                           directory / f"run-{stem}.parquet")


def test_a_format_1_store_loads_and_resumes_to_the_table_of_a_fresh_run(tmp_path):
    tasks = varied_tasks(40, seed=5, failures=False)
    earlier = tasks[:25]
    for task in earlier[::6]:
        task["fail"] = True  # failed in the earlier version: retried now
    write_format_1_store(tmp_path / "old", earlier)
    old = ResultStore(tmp_path / "old")
    assert old.finished_ids() == {t["run_id"] for t in earlier if not t.get("fail")}
    assert old.failed_ids() == {t["run_id"] for t in earlier if t.get("fail")}
    assert len(old.read()) == sum(1 if t.get("fail") else t.get("rows", 1) for t in earlier)
    retried = [{k: v for k, v in t.items() if k != "fail"} for t in tasks]
    resumed = run_tasks(noisy_sum, retried, tmp_path / "old", executor="serial", progress=False)
    fresh = run_tasks(noisy_sum, retried, tmp_path / "fresh", executor="serial", progress=False)
    pd.testing.assert_frame_equal(table(resumed), table(fresh))
    assert not list((tmp_path / "old").glob("error-*"))  # failures retried and finished: their files gone
    assert len(pd.read_parquet(tmp_path / "old")) == len(fresh)


def test_a_store_file_of_a_later_format_is_refused_in_one_line_naming_it(tmp_path):
    run_tasks(noisy_sum, [{"run_id": "a", "seed": 1}], tmp_path, executor="serial", progress=False)
    path = tmp_path / "batch-000001.parquet"
    later = pq.read_table(path)
    pq.write_table(later.replace_schema_metadata({**later.schema.metadata, META_FORMAT: str(FORMAT + 1).encode()}), path)
    for action in (lambda: ResultStore(tmp_path).read(), lambda: run_tasks(noisy_sum, [{"run_id": "b", "seed": 2}], tmp_path, executor="serial", progress=False)):
        with pytest.raises(StoreFormatError) as info:
            action()
        message = str(info.value)
        assert "\n" not in message and f"of format {FORMAT + 1}" in message and str(path) in message
    assert ResultStore(tmp_path).finished_ids  # refused before anything was written
    assert store_files(tmp_path) == ["batch-000001.parquet"]


class InlineExecutor(concurrent.futures.Executor):
    """A minimal custom executor (what an MPI or job-array executor plugs in as): runs each
    call at once in this thread and counts the calls."""

    def __init__(self):
        self.calls = 0
        self.tasks = 0

    def submit(self, fn, /, *args, **kwargs):
        self.calls += 1
        self.tasks += len(args[1]) if fn is call_chunk else 0
        future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:
            future.set_exception(exc)
        return future


@pytest.fixture(scope="module")
def dask_scheduler():
    pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=logging.CRITICAL) as cluster:
        yield cluster.scheduler_address


def test_every_executor_gives_the_same_table(tmp_path, dask_scheduler):
    """Serial, processes, threads, a custom concurrent.futures.Executor and Dask: the same
    table (rows, column order, types), with failures, several rows and no rows."""
    tasks = varied_tasks(300, seed=11)
    inline = InlineExecutor()
    executors = {"serial": "serial", "process": "process", "thread": ThreadPoolExecutor(3), "custom": inline, "dask": "dask"}
    frames = {}
    for name, executor in executors.items():
        frames[name] = table(run_tasks(noisy_sum, tasks, tmp_path / name, executor=executor, workers=2, progress=False,
                                       scheduler=dask_scheduler if name == "dask" else None))
    executors["thread"].shutdown()
    assert frames["serial"]["error"].notna().any() and len(frames["serial"]) > 0
    for name in executors:
        pd.testing.assert_frame_equal(frames[name], frames["serial"], check_dtype=True)
    assert inline.tasks == len(tasks) and inline.calls < len(tasks) // 4  # the custom executor got chunks of tasks


def test_an_executor_instance_with_a_scheduler_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="scheduler: expected None unless executor is 'dask'"):
        run_tasks(noisy_sum, [{"run_id": "a", "seed": 1}], tmp_path, executor=InlineExecutor(), scheduler="tcp://x:1", progress=False)


def test_chunks_start_at_one_task_and_grow_with_the_measured_time():
    sizer = ChunkSizer(workers=2)
    assert sizer.size(pending=1000) == 1
    sizer.record(1, 1e-5)  # 10 µs per task
    assert sizer.size(pending=100_000) == 4  # at most 4× the largest chunk timed
    for size in (4, 16, 64, 256, 1024):
        sizer.record(size, size * 1e-5)
    assert sizer.size(pending=10**7) == min(MAX_CHUNK, 4096)
    assert sizer.size(pending=40) == 10  # an even share of what is left over twice the workers
    slow = ChunkSizer(workers=2)
    slow.record(1, 0.5)
    assert slow.size(pending=1000) == 1  # slow tasks go one by one


def test_records_survive_the_journal_unchanged():
    values = [0.1, -0.0, float("nan"), float("inf"), 2**62, True, None, "é\n", np.float32(0.5), np.int64(7), [1, [2]], {"b": 1}]
    record = Record.of({"run_id": "x", "seed": 1}, "ok", [{f"c{i}": v for i, v in enumerate(values)}])
    back = Record.from_line(record.line())
    assert json.dumps(back.rows, allow_nan=True) == json.dumps(record.rows, allow_nan=True)
    assert [type(v) for v in back.rows[0].values()] == [type(v) for v in record.rows[0].values()]
    assert Record.from_line(record.line()[:-1]) is None


def test_the_workers_of_a_killed_sweep_do_not_keep_its_store_locked(tmp_path):
    """SIGKILL the driving process alone: its worker processes live on for a while, and
    the next sweep on the store must not be refused because of them."""
    store_dir = tmp_path / "store"
    script = textwrap.dedent(
        f"""
        from robofleet.experiments import run_tasks
        from robofleet.experiments._selftest import noisy_sum
        tasks = [{{"run_id": f"t{{i:03d}}", "seed": i, "sleep": 0.5}} for i in range(40)]
        run_tasks(noisy_sum, tasks, {str(store_dir)!r}, executor="process", workers=2, progress=False)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
    try:
        deadline = time.monotonic() + 600
        while len(ResultStore(store_dir).finished_ids()) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        proc.kill()  # the driver only
        proc.wait()
        frame = run_tasks(noisy_sum, [{"run_id": "t000", "seed": 0, "sleep": 0.5}], store_dir, executor="serial", progress=False)
        assert "t000" in set(frame["run_id"])
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the orphaned workers
