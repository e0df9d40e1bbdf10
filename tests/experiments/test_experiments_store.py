"""The Parquet result store: atomic per-task files, resumable ids, failures."""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robofleet.core.errors import ConfigError
from robofleet.experiments import ResultStore, deterministic_columns
from robofleet.experiments import run_tasks
from robofleet.experiments._selftest import noisy_sum
from robofleet.experiments.store import RUN_PREFIX, SUFFIX, DamagedRunWarning, StoreBusyError, check_tasks, file_stem
from urllib.parse import unquote


def test_rows_carry_task_fields_and_task_fields_win(tmp_path):
    store = ResultStore(tmp_path)
    store.write_rows({"run_id": "a", "seed": 3, "speed": 1.5}, [{"x": 1.0, "seed": 99}, {"x": 2.0}])
    frame = store.read()
    assert frame[["run_id", "seed", "speed", "x"]].values.tolist() == [["a", 3, 1.5, 1.0], ["a", 3, 1.5, 2.0]]
    assert frame["error"].isna().all()
    assert store.finished_ids() == {"a"}


def test_interrupted_write_leaves_no_file_and_is_not_finished(tmp_path, monkeypatch):
    store = ResultStore(tmp_path)
    store.write_rows({"run_id": "kept", "seed": 0}, [{"x": 1.0}])

    def write_half_then_die(table, where, **kwargs):
        with open(where, "wb") as handle:
            handle.write(b"PAR1 partial bytes")
        raise KeyboardInterrupt  # what a kill looks like from inside this process

    monkeypatch.setattr(pq, "write_table", write_half_then_die)
    with pytest.raises(KeyboardInterrupt):
        store.write_rows({"run_id": "lost", "seed": 1}, [{"x": 2.0}])
    monkeypatch.undo()
    assert store.finished_ids() == {"kept"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run-kept.parquet"]
    assert store.read()["run_id"].tolist() == ["kept"]


def test_temporaries_of_a_killed_writer_are_ignored_then_removed(tmp_path):
    store = ResultStore(tmp_path)
    store.write_rows({"run_id": "a", "seed": 0}, [{"x": 1.0}])
    stray = tmp_path / ".run-b.parquet.tmp-123-abcdef01"
    stray.write_bytes(b"PAR1 truncated")
    assert store.finished_ids() == {"a"}
    assert store.read()["run_id"].tolist() == ["a"]
    assert store.remove_temporaries() == 1
    assert not stray.exists()


def test_failure_is_kept_then_replaced_by_a_later_success(tmp_path):
    store = ResultStore(tmp_path)
    store.write_error({"run_id": "r", "seed": 5, "p": 1}, "ValueError: boom")
    assert store.finished_ids() == set() and store.failed_ids() == {"r"}
    frame = store.read()
    assert frame[["run_id", "seed", "p", "error"]].values.tolist() == [["r", 5, 1, "ValueError: boom"]]
    store.write_rows({"run_id": "r", "seed": 5, "p": 1}, [{"x": 0.5}])
    assert store.finished_ids() == {"r"} and store.failed_ids() == set()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run-r.parquet"]
    assert store.read()["error"].tolist() == [None]


def test_success_file_wins_over_a_stale_error_file(tmp_path):
    store = ResultStore(tmp_path)
    store.write_rows({"run_id": "r", "seed": 0}, [{"x": 1.0}])
    store.write_error({"run_id": "r", "seed": 0}, "stale")  # as if killed between rename and unlink
    frame = store.read()
    assert len(frame) == 1 and frame["error"].tolist() == [None]


def test_nested_values_become_json_and_mixed_columns_text(tmp_path):
    store = ResultStore(tmp_path)
    store.write_rows({"run_id": "a", "seed": 0, "starts": [[0, 1], [2, 3]]}, [{"v": 1}, {"v": "two"}])
    frame = store.read()
    assert json.loads(frame["starts"][0]) == [[0, 1], [2, 3]]
    assert frame["v"].tolist() == ["1", "two"]


def test_task_without_rows_is_recorded(tmp_path):
    store = ResultStore(tmp_path)
    store.write_rows({"run_id": "empty", "seed": 0, "p": 2.0}, [])
    assert store.finished_ids() == {"empty"}
    assert len(store.read()) == 0


def test_empty_store_reads_as_empty_frame_with_key_columns(tmp_path):
    frame = ResultStore(tmp_path / "missing").read()
    assert len(frame) == 0 and {"run_id", "seed", "error"} <= set(frame.columns)


def test_schemas_differing_between_files_are_unified(tmp_path):
    store = ResultStore(tmp_path)
    store.write_rows({"run_id": "a", "seed": 0}, [{"x": None}])
    store.write_rows({"run_id": "b", "seed": 1}, [{"x": 2.5, "y": True}])
    frame = store.read()
    assert frame["x"].tolist()[1] == 2.5 and frame["y"].tolist()[1] is True


@settings(max_examples=60, deadline=None)
@given(st.text(min_size=1, max_size=60))
def test_any_run_id_round_trips_through_a_file_name(run_id):
    stem = file_stem(run_id)
    name = RUN_PREFIX + stem + SUFFIX  # what is written; never "." or ".." thanks to the prefix
    assert "/" not in name and "\x00" not in name and not name.startswith(".")
    assert unquote(stem) == run_id


def test_run_ids_with_slashes_and_dots_are_stored_and_listed(tmp_path):
    store = ResultStore(tmp_path)
    for run_id in ["method=bvc/seed=3", "..", "a b%2F"]:
        store.write_rows({"run_id": run_id, "seed": 0}, [{"x": 1}])
    assert store.finished_ids() == {"method=bvc/seed=3", "..", "a b%2F"}
    assert all(p.parent == tmp_path for p in tmp_path.iterdir())


@pytest.mark.parametrize(
    "tasks, words",
    [
        ([{"seed": 1}], "run_id"),
        ([{"run_id": "", "seed": 1}], "run_id"),
        ([{"run_id": "a", "seed": True}], "seed"),
        ([{"run_id": "a", "seed": -1}], "seed"),
        ([{"run_id": "a", "seed": 1.0}], "seed"),
        ([{"run_id": "a", "seed": 1}, {"run_id": "a", "seed": 2}], "duplicate"),
        ([{"run_id": "a", "seed": 1, "error": "x"}], "reserved"),
        ([{"run_id": "x" * 300, "seed": 1}], "run_id"),
        (["not a dict"], "tasks[0]"),
    ],
)
def test_malformed_tasks_raise_one_line_config_errors(tasks, words):
    with pytest.raises(ConfigError) as info:
        check_tasks(tasks)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_timing_columns_are_left_out_of_determinism_checks():
    import pandas as pd

    frame = pd.DataFrame(columns=["run_id", "seed", "median_step_seconds", "compute_seconds", "makespan"])
    assert deterministic_columns(frame) == ["run_id", "seed", "makespan"]


def test_a_truncated_run_file_is_set_aside_with_one_warning_and_redone(tmp_path):
    store = ResultStore(tmp_path)
    tasks = [{"run_id": f"t{i}", "seed": i} for i in range(3)]
    run_tasks(noisy_sum, tasks[:1], store, executor="serial", progress=False)
    run_tasks(noisy_sum, tasks, store, executor="serial", progress=False)  # t1 and t2 in a second file
    victim = next(p for p in tmp_path.glob("*.parquet") if "t1" in pq.read_table(p)["run_id"].to_pylist())
    victim.write_bytes(victim.read_bytes()[:40])  # what a crash mid-write without the rename could leave
    with pytest.warns(DamagedRunWarning, match=f"{victim.name}: set aside") as caught:
        frame = run_tasks(noisy_sum, tasks, store, executor="serial", progress=False)
    assert len(caught) == 1
    assert sorted(frame["run_id"]) == ["t0", "t1", "t2"] and frame["error"].isna().all()
    assert (tmp_path / "_damaged" / victim.name).is_file()
    assert sorted(pd.read_parquet(tmp_path)["run_id"]) == ["t0", "t1", "t2"]  # readers skip the _damaged folder


def test_a_store_file_unreadable_inside_is_set_aside_when_read(tmp_path):
    store = ResultStore(tmp_path)
    run_tasks(noisy_sum, [{"run_id": "a", "seed": 1}], store, executor="serial", progress=False)
    run_tasks(noisy_sum, [{"run_id": "b", "seed": 2}], store, executor="serial", progress=False)
    path = next(p for p in tmp_path.glob("*.parquet") if pq.read_table(p)["run_id"].to_pylist() == ["b"])
    data = bytearray(path.read_bytes())
    data[4:60] = bytes(56)  # damaged inside, magic bytes intact
    path.write_bytes(bytes(data))
    with pytest.warns(DamagedRunWarning, match="unreadable"):
        frame = store.read()
    assert list(frame["run_id"]) == ["a"] and not path.exists()


def test_every_store_file_gets_the_same_columns_so_pandas_and_polars_read_all_rows(tmp_path):
    polars = pytest.importorskip("polars")
    tasks = [{"run_id": "ok", "seed": 1}, {"run_id": "bad", "seed": 2, "fail": True}, {"run_id": "rows", "seed": 3, "rows": 2}]
    for task in tasks:  # one store file each, with different columns
        run_tasks(noisy_sum, [task], tmp_path, executor="serial", progress=False)
    schemas = {p.name: pq.read_schema(p) for p in tmp_path.glob("*.parquet")}
    assert len(schemas) == 3 and len({s.to_string(show_schema_metadata=False) for s in schemas.values()}) == 1
    assert len(pd.read_parquet(tmp_path)) == 4
    frame = polars.read_parquet(str(tmp_path / "*.parquet"))
    assert frame.height == 4 and "error" in frame.columns


def test_a_second_writer_on_the_same_store_is_refused_in_one_line(tmp_path):
    script = (
        "import sys, time\n"
        "from robofleet.experiments import ResultStore\n"
        f"with ResultStore({str(tmp_path)!r}).writer_lock():\n"
        "    print('locked', flush=True)\n"
        "    time.sleep(30)\n"
    )
    holder = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(StoreBusyError, match=rf"which process {holder.pid} is writing"):
            run_tasks(noisy_sum, [{"run_id": "a", "seed": 1}], tmp_path, executor="serial", progress=False)
    finally:
        holder.kill()
        holder.wait()
    run_tasks(noisy_sum, [{"run_id": "a", "seed": 1}], tmp_path, executor="serial", progress=False)  # free again
    assert ResultStore(tmp_path).finished_ids() == {"a"}
