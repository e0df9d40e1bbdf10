"""A damaged but parseable trace is refused with one line naming the file and the field,
by :meth:`Trace.load` and by every command that reads runs (``robofleet view``), never
with a traceback.

A valid trace of each family is damaged in every way the rules of
:mod:`robofleet.core.trace_check` cover: each metadata and results field given a value of
another kind or removed, each field of an event of each kind given another kind (or
removed), each array reshaped, retyped, removed, or joined by an unlisted one, the files
truncated or replaced, the document's own structure broken. Events are columns of
``trace.npz`` (version 4: each column damaged like any array, and its values or its
description in ``trace.json`` broken); a version 3 trace (events a list in ``trace.json``)
still loads, and each field of its events damaged is named the same way."""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import robofleet
from robofleet.cli.main import main
from robofleet.core.errors import TraceError
from robofleet.core.events import Events
from robofleet.core.trace import Trace
from robofleet.scenarios import FAMILIES

RUNS = {  # family: (scenario, budget): short runs that record events of every kind they have
    "avoidance": ("avoidance/double_integrator", 150),
    "coordination": ("coordination/x_corridor_5_tff", 400),
    "flocking": ("flocking/wedge_async", 20),
    "search": ("search/failure_injection", 8),
}


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> dict[str, Path]:
    """family → directory of a valid saved trace of it."""
    root = tmp_path_factory.mktemp("valid")
    out = {}
    for family, (scenario, budget) in RUNS.items():
        spec = robofleet.load_scenario(scenario, {FAMILIES[family].budget: budget})
        out[family] = robofleet.simulate(spec, seed=2).save(root / family)
    return out


def other_kind(value):
    """A value of another JSON kind than ``value``."""
    if isinstance(value, str):
        return 7
    if isinstance(value, bool) or value is None:
        return "yes"
    if isinstance(value, (int, float)):
        return "seven"
    if isinstance(value, list):
        return 5
    return [1, 2]


Damage = Callable[[dict, dict], None]  # (trace.json document, arrays) → damaged in place


def damages_of(directory: Path) -> dict[str, tuple[str, str, Damage]]:
    """name → (file named in the message, field named in it, damage), for a valid trace."""
    doc = json.loads((directory / "trace.json").read_text())
    with np.load(directory / "trace.npz") as npz:
        arrays = {k: npz[k] for k in npz.files}
    out: dict[str, tuple[str, str, Damage]] = {}

    def add(name, file, field, damage):
        out[name] = (file, field, damage)

    for part in ("metadata", "results"):
        for key, value in doc[part].items():
            add(f"{part}.{key} of another kind", "trace.json", f"{part}.{key}",
                lambda d, a, part=part, key=key, value=value: d[part].__setitem__(key, other_kind(value)))
            add(f"{part}.{key} removed", "trace.json", f"{part}.{key}", lambda d, a, part=part, key=key: d[part].pop(key))
    for key, array in arrays.items():
        if array.ndim and len(array):
            add(f"{key} one row short", "trace.npz", key, lambda d, a, key=key: a.__setitem__(key, a[key][:-1]))
        add(f"{key} of text", "trace.npz", key, lambda d, a, key=key: a.__setitem__(key, a[key].astype(str)))
        other = np.float32 if array.dtype.kind == "f" else np.float64
        add(f"{key} of another dtype", "trace.npz", key, lambda d, a, key=key, other=other: a.__setitem__(key, a[key].astype(other)))
        add(f"{key} removed", "trace.npz", key, lambda d, a, key=key: a.pop(key))
    add("an unlisted array", "trace.npz", "extra", lambda d, a: a.__setitem__("extra", np.zeros(3)))
    add("positions reshaped with the schema", "trace.npz", "positions", reshaped_positions_and_schema)
    add("family of another kind", "trace.json", "family", lambda d, a: d.__setitem__("family", 7))
    add("metadata not an object", "trace.json", "metadata", lambda d, a: d.__setitem__("metadata", [1]))
    add("results not an object", "trace.json", "results", lambda d, a: d.__setitem__("results", "x"))
    add("events not a table", "trace.json", "events", lambda d, a: d.__setitem__("events", {"step": 1}))
    add("events a list", "trace.json", "events", lambda d, a: d.__setitem__("events", [5]))
    add("an event count off by one", "trace.json", "events.count", lambda d, a: d["events"].__setitem__("count", d["events"]["count"] + 1))
    add("an event kind table broken", "trace.json", "events.kinds", lambda d, a: d["events"].__setitem__("kinds", ["x", "x"]))
    add("an event field of an unknown kind", "trace.json", "events.fields.z",
        lambda d, a: d["events"]["fields"].__setitem__("z", {"kind": "tensor", "partial": False}))
    if len(arrays["events.step"]):
        add("a step past the run", "trace.npz", "events.step",
            lambda d, a: a["events.step"].__setitem__(-1, d["metadata"]["n_steps"] + 1))
        add("a kind code past the table", "trace.npz", "events.kind",
            lambda d, a: a["events.kind"].__setitem__(0, len(d["events"]["kinds"])))
    if "events.robot" in arrays and len(arrays["events.robot"]):
        add("a robot that is not in the run", "trace.npz", "events.robot",
            lambda d, a: a["events.robot"].__setitem__(0, d["metadata"]["n_robots"]))
    for name, entry in doc["events"]["fields"].items():
        add(f"event field {name} undescribed", "trace.npz", f"events.{name}", lambda d, a, name=name: d["events"]["fields"].pop(name))
        if entry["kind"].startswith("list of"):
            add(f"event field {name}: offsets past the items", "trace.npz", f"events.{name}:offsets",
                lambda d, a, name=name: a[f"events.{name}:offsets"].__setitem__(-1, len(a[f"events.{name}"]) + 1))
    add("schema removed", "trace.json", "schema", lambda d, a: d.pop("schema"))
    add("schema of another kind", "trace.json", "schema", lambda d, a: d.__setitem__("schema", [1]))
    add("schema null", "trace.json", "schema", lambda d, a: d.__setitem__("schema", None))
    add("a schema kind of another kind", "trace.json", "schema.metadata.seed", lambda d, a: d["schema"]["metadata"].__setitem__("seed", 5))
    add("a schema event entry broken", "trace.json", "schema.events", lambda d, a: d["schema"]["events"].__setitem__("x", {"step": 5}))
    add("a schema array entry broken", "trace.json", "schema.arrays.positions",
        lambda d, a: d["schema"]["arrays"].__setitem__("positions", {"dtype": "float64", "shape": [-1]}))
    add("unknown version", "trace.json", "version", lambda d, a: d.__setitem__("version", 99))
    add("a negative seed", "trace.json", "metadata.seed", lambda d, a: d["metadata"].__setitem__("seed", -1))
    add("record_every zero", "trace.json", "metadata.record_every", lambda d, a: d["metadata"].__setitem__("record_every", 0))
    return out


def event_damages_of_version_3(directory: Path) -> dict[str, tuple[str, str, Damage]]:
    """name → (file, field, damage) of the events of the version 3 form of a trace."""
    doc = json.loads((directory / "trace.json").read_text())
    out: dict[str, tuple[str, str, Damage]] = {}
    first = {}
    for index, event in enumerate(doc["events"]):
        first.setdefault(event["kind"], index)
    for kind, index in first.items():
        required = {name for name, k in doc["schema"]["events"][kind].items() if not k.startswith("optional ")}
        for key, value in doc["events"][index].items():
            out[f"events[{index}].{key} of another kind"] = ("trace.json", f"events[{index}].{key}",
                lambda d, a, index=index, key=key, value=value: d["events"][index].__setitem__(key, other_kind(value)))
            if key in required:
                out[f"events[{index}].{key} removed"] = ("trace.json", f"events[{index}].{key}",
                                                        lambda d, a, index=index, key=key: d["events"][index].pop(key))
    out["events not a list"] = ("trace.json", "events", lambda d, a: d.__setitem__("events", {"step": 1}))
    out["an event not an object"] = ("trace.json", "events[0]", lambda d, a: d.__setitem__("events", [5]))
    out["a step past the run"] = ("trace.json", "events[0].step",
                                  lambda d, a: d.__setitem__("events", [{"step": d["metadata"]["n_steps"] + 1, "kind": "x"}]))
    out["a robot that is not in the run"] = ("trace.json", "events[0].robot",
                                             lambda d, a: d.__setitem__("events", [{"step": 0, "kind": "x", "robot": d["metadata"]["n_robots"]}]))
    return out


def as_version_3(doc: dict, arrays: dict) -> None:
    """The trace as version 3 wrote it: its events a list of objects in ``trace.json``."""
    events = Events.from_arrays(doc["events"], arrays)
    for name in [n for n in arrays if n.startswith("events.")]:
        arrays.pop(name)
        doc["schema"]["arrays"].pop(name)
    doc["events"] = list(events)
    doc["version"] = 3


def as_version_2(doc: dict, arrays: dict) -> None:
    """The trace as version 2 wrote it: version 3 without the schema."""
    as_version_3(doc, arrays)
    doc.pop("schema")
    doc["version"] = 2


def reshaped_positions_and_schema(doc: dict, arrays: dict) -> None:
    """positions a row short, and the schema edited to match: the metadata still disagree."""
    arrays["positions"] = arrays["positions"][:-1]
    doc["schema"]["arrays"]["positions"]["shape"][0] -= 1


def damaged_copy(directory: Path, target: Path, damage: Damage) -> Path:
    shutil.copytree(directory, target)
    doc = json.loads((target / "trace.json").read_text())
    with np.load(target / "trace.npz") as npz:
        arrays = {k: npz[k] for k in npz.files}
    damage(doc, arrays)
    (target / "trace.json").write_text(json.dumps(doc))
    np.savez_compressed(target / "trace.npz", **arrays)
    return target


FILE_DAMAGES = {  # name → (file named, what is written over it)
    "trace.npz truncated": ("trace.npz", lambda data: data[: len(data) // 2]),
    "trace.npz of garbage": ("trace.npz", lambda data: b"not a zip file"),
    "trace.npz empty": ("trace.npz", lambda data: b""),
    "trace.json truncated": ("trace.json", lambda data: data[: len(data) // 2]),
    "trace.json a list": ("trace.json", lambda data: b"[1, 2]"),
    "trace.json not UTF-8": ("trace.json", lambda data: b"\xff\xfe{"),
}


def assert_one_line_naming(message: str, file: Path, field: str) -> None:
    assert "\n" not in message and "Traceback" not in message, message
    assert str(file) in message and field in message, (message, file, field)


def assert_refused_in_one_line(run, name: str, file: str, field: str, capsys) -> None:
    """``Trace.load`` and ``robofleet view`` refuse the damaged ``run`` in one line (status 2
    for the command) naming the damaged file and field."""
    with pytest.raises(TraceError) as info:
        Trace.load(run)
    assert_one_line_naming(str(info.value), run / file, field)
    with pytest.raises(SystemExit) as stop:
        main(["view", str(run), "--no-open"])
    err = capsys.readouterr().err
    assert stop.value.code == 2, (name, err)
    assert err.count("\n") == 1 and err.startswith("error: "), (name, err)
    assert_one_line_naming(err.strip(), run / file, field)


@pytest.mark.parametrize("family", list(RUNS))
def test_every_damage_is_one_line_from_trace_load_and_from_view(family, saved, tmp_path, capsys):
    damages = damages_of(saved[family])
    assert len(damages) > 40
    for index, (name, (file, field, damage)) in enumerate(damages.items()):
        assert_refused_in_one_line(damaged_copy(saved[family], tmp_path / str(index), damage), name, file, field, capsys)


@pytest.mark.parametrize("family", list(RUNS))
def test_every_event_damage_of_a_version_3_trace_is_one_line(family, saved, tmp_path, capsys):
    old = damaged_copy(saved[family], tmp_path / "v3", as_version_3)
    loaded = Trace.load(old)
    assert json.loads((old / "trace.json").read_text())["version"] == 3 and loaded.events == Trace.load(saved[family]).events
    for index, (name, (file, field, damage)) in enumerate(event_damages_of_version_3(old).items()):
        assert_refused_in_one_line(damaged_copy(old, tmp_path / str(index), damage), name, file, field, capsys)


@pytest.mark.parametrize("name", list(FILE_DAMAGES))
def test_damaged_files_are_one_line_naming_the_file(name, saved, tmp_path, capsys):
    file, rewrite = FILE_DAMAGES[name]
    run = shutil.copytree(saved["search"], tmp_path / "run")
    (run / file).write_bytes(rewrite((run / file).read_bytes()))
    with pytest.raises(TraceError) as info:
        Trace.load(run)
    assert_one_line_naming(str(info.value), run / file, file)
    with pytest.raises(SystemExit) as stop:
        main(["view", str(run), "--no-open"])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err.count("\n") == 1 and str(run / file) in err, err


def test_the_command_line_prints_one_line_and_exits_2(saved, tmp_path, robofleet_bin):
    run = damaged_copy(saved["avoidance"], tmp_path / "run", lambda d, a: d["metadata"].__setitem__("radius", "big"))
    result = subprocess.run([str(robofleet_bin), "view", str(run), "--no-open"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr == f"error: {run / 'trace.json'}: metadata.radius: expected a value of kind number (as written), received 'big'\n"


def test_a_trace_without_schema_still_loads_and_view_stays_one_line(saved, tmp_path, capsys):
    """A version 2 trace (written before the schema was recorded) loads; a value of the
    wrong kind in it, that only the replay meets, still ends as one line."""
    for family, directory in saved.items():
        run = damaged_copy(directory, tmp_path / family, as_version_2)
        assert Trace.load(run).summary() == Trace.load(directory).summary()
        assert Trace.load(run).events == Trace.load(directory).events
        doc = json.loads((run / "trace.json").read_text())
        for index, key in enumerate(doc["metadata"]):
            if key in ("scenario", "seed", "n_robots", "n_steps", "max_steps", "record_every", "wall_seconds"):
                continue
            broken = damaged_copy(run, tmp_path / f"{family}-{index}", lambda d, a, key=key: d["metadata"].__setitem__(key, other_kind(d["metadata"][key])))
            try:
                main(["view", str(broken), "--no-open", "--out", str(tmp_path / "page.html"), "--overwrite"])
            except SystemExit as stop:
                err = capsys.readouterr().err
                assert stop.code == 2 and err.count("\n") == 1 and err.startswith(f"error: {broken}"), (key, err)
            capsys.readouterr()


def test_every_valid_trace_round_trips(saved):
    for directory in saved.values():
        trace = Trace.load(directory)
        again = Trace.load(trace.save(directory.parent / f"{directory.name}-again"))
        assert again.summary() == trace.summary() and again.events == trace.events
        for key, array in trace.arrays.items():
            np.testing.assert_array_equal(again.arrays[key], array)


def random_value(rng):
    return [None, True, -3, 2.5, "x", "__DATA__", [], [1, "a"], {"k": 1}, [[0.0, 1.0]], 10**30][rng.integers(11)]


def mutate_document(doc, rng) -> None:
    """Replace or remove one value at a random place of the document (any depth)."""
    node, depth = doc, 0
    while True:
        keys = list(node) if isinstance(node, dict) else list(range(len(node)))
        if not keys:
            return
        key = keys[rng.integers(len(keys))]
        child = node[key]
        if isinstance(child, (dict, list)) and child and rng.random() < 0.7 and depth < 6:
            node, depth = child, depth + 1
            continue
        if isinstance(node, dict) and rng.random() < 0.3:
            node.pop(key)
        else:
            node[key] = random_value(rng)
        return


def mutate_bytes(data: bytes, rng) -> bytes:
    if rng.random() < 0.5:
        return data[: rng.integers(len(data))]
    flipped = bytearray(data)
    for _ in range(rng.integers(1, 4)):
        flipped[rng.integers(len(flipped))] ^= 1 << int(rng.integers(8))
    return bytes(flipped)


def test_random_damage_is_refused_in_one_line_or_read_and_viewed(saved, tmp_path, capsys):
    """Seeded random damage anywhere in either file: Trace.load returns a trace or raises
    one TraceError line, never another error; view of what loads is a page or one line."""
    rng = np.random.default_rng(20)
    outcomes = {"refused": 0, "loaded": 0}
    for case in range(600):
        family = list(saved)[case % len(saved)]
        run = shutil.copytree(saved[family], tmp_path / str(case))
        if rng.random() < 0.6:
            doc = json.loads((run / "trace.json").read_text())
            mutate_document(doc, rng)
            (run / "trace.json").write_text(json.dumps(doc))
        else:
            name = ["trace.json", "trace.npz"][rng.integers(2)]
            (run / name).write_bytes(mutate_bytes((run / name).read_bytes(), rng))
        try:
            Trace.load(run)
        except TraceError as exc:
            assert "\n" not in str(exc) and str(run) in str(exc), str(exc)
            outcomes["refused"] += 1
            continue
        outcomes["loaded"] += 1
        try:
            main(["view", str(run), "--no-open"])
        except SystemExit as stop:
            err = capsys.readouterr().err
            assert stop.code == 2 and err.count("\n") == 1 and err.startswith("error: "), err
        capsys.readouterr()
    assert outcomes["refused"] > 300 and outcomes["loaded"] > 0, outcomes
