"""Events as columns (:mod:`robofleet.core.events`, trace version 4): ``trace.json`` holds
their description only, ``trace.npz`` their columns; any list of event dicts round-trips
(seeded random events of every value kind, split into batches and dicts in any order);
runs of one seed give identical columns; saving allocates little beyond the arrays;
traces of versions 2 and 3 load and other versions are refused in one line."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest

import robofleet
from robofleet.core.errors import ConfigError, TraceError
from robofleet.core.events import EventLog, Events
from robofleet.core.recorder import Recorder
from robofleet.core.trace import TRACE_VERSION, Trace


@pytest.fixture(scope="module")
def crowd() -> Trace:
    """A dense circle swap whose robots report deadlocks and empty cells."""
    spec = robofleet.load_scenario("avoidance/circle_swap", {"robots.n": 24, "max_steps": 120, "robots.layout.radius": 2.4})
    return robofleet.simulate(spec, seed=5)


def test_trace_json_describes_the_events_and_the_npz_holds_their_columns(crowd, tmp_path):
    directory = crowd.save(tmp_path / "run")
    doc = json.loads((directory / "trace.json").read_text())
    assert doc["version"] == TRACE_VERSION == 4
    assert doc["events"]["count"] == len(crowd.events) > 50 and set(doc["events"]["kinds"]) >= {"deadlock", "empty_cell"}
    assert doc["events"]["fields"] == {"robot": {"kind": "integer", "partial": False}}
    with np.load(directory / "trace.npz") as npz:
        np.testing.assert_array_equal(npz["events.step"], crowd.events.steps)
        np.testing.assert_array_equal(npz["events.robot"], crowd.events.column("robot"))
    assert "step" not in (directory / "trace.json").read_text().split('"schema"')[0].split('"events"')[1].split('"metadata"')[0]
    loaded = Trace.load(directory)
    assert loaded.events == crowd.events and list(loaded.events) == list(crowd.events)
    assert not any(name.startswith("events.") for name in loaded.arrays)


def test_the_table_reads_as_the_list_of_dicts_and_by_column(crowd):
    events, rows = crowd.events, list(crowd.events)
    assert events == rows and rows == events and events[-1] == rows[-1] and list(events[3:9]) == rows[3:9]
    assert events.counts() == {k: sum(e["kind"] == k for e in rows) for k in events.kinds}
    deadlocks = events.kind_mask("deadlock")
    assert events.take(deadlocks) == [e for e in rows if e["kind"] == "deadlock"]
    assert events.column("robot").tolist() == [e.get("robot", -1) for e in rows]
    with pytest.raises(IndexError):
        events[len(rows)]


def random_value(rng):
    """A value of any kind an event field may hold."""
    choice = rng.integers(12)
    return [lambda: int(rng.integers(-5, 50)), lambda: float(rng.normal()), lambda: bool(rng.integers(2)),
            lambda: ["own", "received", "</script>", ""][rng.integers(4)], lambda: [int(x) for x in rng.integers(0, 9, rng.integers(0, 4))],
            lambda: rng.normal(size=2).tolist(), lambda: None, lambda: {"k": int(rng.integers(3))}, lambda: [[1, 2], [3]],
            lambda: np.int64(rng.integers(100)), lambda: np.float32(0.5), lambda: 10**30][choice]()


def plain(value):
    return value.item() if isinstance(value, np.generic) else value


def random_events(rng, count: int) -> list[dict]:
    kinds = ["arrived", "deadlock", "flip", "stop", "cycle"]
    fields = ["robot", "other", "rule", "robots", "start", "t_look", "x"]
    rows = []
    for step in sorted(rng.integers(0, 40, count).tolist()):
        row = {"step": step, "kind": kinds[rng.integers(len(kinds))]}
        for name in rng.choice(fields, rng.integers(0, 4), replace=False):
            row[str(name)] = random_value(rng)
        rows.append(row)
    return rows


@pytest.mark.parametrize("seed", range(6))
def test_any_list_of_events_round_trips_through_the_table_and_the_files(seed, tmp_path):
    rng = np.random.default_rng(seed)
    rows = random_events(rng, int(rng.integers(0, 60)))
    expected = [{k: plain(v) for k, v in row.items()} for row in rows]
    table = Events.from_records(rows)
    assert table == expected and list(table) == expected
    log = EventLog()  # the same events through a recorder's log: dicts and batches of one kind, in order
    for row in rows:
        if set(row) == {"step", "kind", "robot"} and isinstance(row["robot"], (int, np.integer)) and rng.random() < 0.5:
            log.add(row["step"], row["kind"], robot=np.array([row["robot"]]))
        else:
            log.append(row)
    assert log.table() == expected and list(log) == expected
    trace = Trace("search", {}, rows, {"n_steps": 40, "n_robots": 50}, {})
    loaded = Trace.load(trace.save(tmp_path / "run"))
    assert loaded.events == expected
    assert Events.concat([table[:len(rows) // 2], table[len(rows) // 2:]]) == expected


def test_an_event_without_step_or_kind_is_refused_in_one_line():
    for bad in ([{"kind": "x"}], [{"step": 1}], [{"step": "1", "kind": "x"}], [5]):
        with pytest.raises(ConfigError, match=r"events\[0\]: expected an event with an integer step and a kind") as info:
            Events.from_records(bad)
        assert "\n" not in str(info.value)


def test_a_batch_for_every_flagged_robot_keeps_the_order_of_the_dicts():
    rec = Recorder(max_steps=5, n_robots=4)
    rec.event(0, "start")
    rec.events_for(0, "deadlock", np.array([True, False, True, False]))
    rec.event(1, "flip", robot=2, other=0)
    rec.events_for(1, "deadlock", np.zeros(4, bool))
    rec.arrive(2, np.array([False, True, False, False]))
    assert rec.events.count_of("deadlock") == 2 and len(rec.events) == 5
    expected = [{"step": 0, "kind": "start"}, {"step": 0, "kind": "deadlock", "robot": 0}, {"step": 0, "kind": "deadlock", "robot": 2},
                {"step": 1, "kind": "flip", "robot": 2, "other": 0}, {"step": 2, "kind": "arrived", "robot": 1}]
    assert list(rec.events) == expected and rec.events.table() == expected


def test_runs_of_one_seed_give_identical_event_columns(crowd):
    spec = robofleet.load_scenario("avoidance/circle_swap", {"robots.n": 24, "max_steps": 120, "robots.layout.radius": 2.4})
    again = robofleet.simulate(spec, seed=5)
    a, b = crowd.events.to_arrays(), again.events.to_arrays()
    assert sorted(a) == sorted(b) and crowd.events.describe() == again.events.describe()
    for name in a:
        assert a[name].dtype == b[name].dtype and np.array_equal(a[name], b[name]), name


def test_saving_allocates_little_beyond_the_arrays(tmp_path):
    """Half a million events and 24 MB of arrays: the memory allocated while saving stays
    under a quarter of what is saved (numpy writes each array in chunks of 16 MiB)."""
    rng = np.random.default_rng(0)
    n_steps, n_robots = 1500, 1000
    rec = Recorder(max_steps=n_steps, n_robots=n_robots)
    rec.state("positions", (n_robots, 2), initial=np.zeros((n_robots, 2)))

    def step(k):
        rec.put_state(k + 1, positions=np.full((n_robots, 2), k * 0.01))
        rec.events_for(k, "deadlock", rng.random(n_robots) < 0.3)
        return False

    rec.run(step)
    trace = rec.trace("avoidance", scenario="memory", seed=0)
    saved = sum(a.nbytes for a in trace.arrays.values()) + sum(a.nbytes for a in trace.events.to_arrays().values())
    assert len(trace.events) > 400_000
    tracemalloc.start()
    try:
        trace.save(tmp_path / "run")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < saved / 4, (peak, saved)
    assert (tmp_path / "run" / "trace.json").stat().st_size < 20_000


def test_an_array_named_like_an_event_column_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="events.step"):
        Trace("search", {"events.step": np.zeros(3)}, [], {}, {}).save(tmp_path / "run")


@pytest.mark.parametrize("version", [1, 5, "4"])
def test_other_versions_are_refused_in_one_line_naming_the_version(crowd, tmp_path, version):
    directory = crowd.save(tmp_path / "run")
    doc = json.loads((directory / "trace.json").read_text())
    doc["version"] = version
    (directory / "trace.json").write_text(json.dumps(doc))
    with pytest.raises(TraceError) as info:
        Trace.load(directory)
    message = str(info.value)
    assert "\n" not in message and "version: expected one of [2, 3, 4]" in message and repr(version) in message
