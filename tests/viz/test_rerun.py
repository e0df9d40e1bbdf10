"""``robofleet view RUN --rerun FILE.rrd``: a Rerun recording with the page's layers on one
time axis, read back from the file (skipped, with the reason, without the rerun extra)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from robofleet.cli.main import main
from robofleet.viz.replay import avoidance, coordination, flocking, search
from robofleet.viz.replay.rerun_export import TIME_AXIS, entity_name

BUILDERS = {"avoidance": avoidance, "avoidance_3d": avoidance, "coordination": coordination, "flocking": flocking,
            "search": search}
pytestmark = pytest.mark.skipif(importlib.util.find_spec("rerun") is None,
                                reason="the rerun extra is not installed (pip install 'robofleet[rerun]'): no .rrd is written or read")


def read_back(path):
    """entity path → (timelines, rows of each component column, number of distinct times, columns)."""
    import pyarrow as pa
    import rerun as rr

    entities: dict[str, dict] = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        batch = pa.Table.from_batches([chunk.to_record_batch()])
        entry = entities.setdefault(chunk.entity_path, {"timelines": set(), "times": set(), "columns": set(), "batches": []})
        entry["timelines"].update(chunk.timeline_names)
        entry["columns"].update(batch.column_names)
        if TIME_AXIS in batch.column_names:
            entry["times"].update(batch.column(TIME_AXIS).to_pylist())
        entry["batches"].append(batch)
    return entities


@pytest.mark.parametrize("name", list(BUILDERS))
def test_the_recording_holds_every_layer_on_one_time_axis(traces, tmp_path, name, capsys):
    run = traces[name].save(tmp_path / "run")
    main(["view", str(run), "--no-open", "--rerun", str(tmp_path / "run.rrd")])
    assert "run.rrd" in capsys.readouterr().out
    scene = BUILDERS[name].replay_scene(traces[name])
    entities = read_back(tmp_path / "run.rrd")
    timelines = set().union(*(e["timelines"] for e in entities.values()))
    assert timelines == {TIME_AXIS}
    robots = entities["/world/robots"]
    assert len(robots["times"]) == scene.n_frames
    groups = {entity_name(g) for g in scene.groups()}
    logged = {path.split("/")[2] for path in entities if path.count("/") >= 2}
    assert groups <= logged, groups - logged
    position_column = next(c for c in robots["columns"] if c.endswith(":positions"))
    rows = [row for b in robots["batches"] if position_column in b.column_names for row in b.column(position_column).to_pylist() if row]
    assert {len(row) for row in rows} == {scene.n_robots}
    assert {len(p) for row in rows for p in row} == {scene.positions.shape[2]}  # 3-D points for 3-D runs
    if name == "avoidance_3d":
        assert "/world/obstacles/boxes" in entities
        first = np.array(rows[0])
        np.testing.assert_allclose(first, scene.positions[0], atol=1e-5)


def test_a_recording_is_replaced_whole_and_only_if_robofleet_wrote_it(traces, tmp_path, capsys):
    from robofleet.viz.replay.rerun_export import is_robofleet_recording

    run = traces["search"].save(tmp_path / "run")
    recording = tmp_path / "run.rrd"
    for _ in range(2):  # the second time over robofleet's own recording: no --overwrite needed
        main(["view", str(run), "--no-open", "--out", str(tmp_path / "page.html"), "--rerun", str(recording)])
        assert is_robofleet_recording(recording) and read_back(recording)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page.html", "run", "run.rrd"]  # no temporaries left
    capsys.readouterr()
    foreign = tmp_path / "other.rrd"
    foreign.write_bytes(recording.read_bytes().replace(b"robofleet", b"elsewhere"))
    with pytest.raises(SystemExit) as stop:
        main(["view", str(run), "--no-open", "--out", str(tmp_path / "page.html"), "--rerun", str(foreign)])
    assert stop.value.code == 2 and "--rerun" in capsys.readouterr().err


def test_a_recording_sent_in_small_blocks_holds_the_same_rows(traces, tmp_path, monkeypatch):
    """Robots, layers and events sent a few items at a time (as large scenes are) give the
    same rows at the same times as one block each."""
    from robofleet.viz.replay import rerun_export

    scene = BUILDERS["avoidance"].replay_scene(traces["avoidance"])
    whole = read_back(rerun_export.write_rrd(scene, tmp_path / "whole.rrd"))
    monkeypatch.setattr(rerun_export, "ITEMS_PER_BLOCK", 7)
    monkeypatch.setattr(rerun_export, "EVENTS_PER_CHUNK", 3)
    blocks = read_back(rerun_export.write_rrd(scene, tmp_path / "blocks.rrd"))
    assert set(whole) == set(blocks)
    for entity, entry in whole.items():
        assert entry["times"] == blocks[entity]["times"], entity
        for column in entry["columns"]:
            if column.endswith(("positions", "strips", "text", "colors")):
                rows = lambda e: sorted(str(r) for b in e["batches"] if column in b.column_names for r in b.column(column).to_pylist())  # noqa: E731
                assert rows(entry) == rows(blocks[entity]), (entity, column)
