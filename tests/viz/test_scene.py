"""Replay scenes of every family: what they hold, how they encode, the pieces computed from
the trace (cells, who waits for whom, visited vertices), and ``robofleet view``."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from robofleet.cli.main import main
from robofleet.core.errors import ConfigError
from robofleet.core.trace import Trace
from robofleet.viz import avoidance_geometry
from robofleet.viz.replay import avoidance, coordination, flocking, search
from robofleet.viz.replay.page import replay_html
from robofleet.viz.replay.report import markdown_html, report_html
from robofleet.viz.replay.scene import decode_array, encode_array
from robofleet.viz.replay.target import locate

BUILDERS = {"avoidance": avoidance, "avoidance_3d": avoidance, "coordination": coordination, "flocking": flocking,
            "search": search}
EXPECTED_GROUPS = {  # what each family's replay must show
    "avoidance": {"cells", "uncertainty (3σ)", "goals", "workspace"},
    "avoidance_3d": {"goals", "obstacles", "headings"},
    "coordination": {"planned paths", "disturbance", "obstacles", "waits for", "flips"},
    "flocking": {"pattern", "estimated target (slots)", "Move (to its destination)", "Look"},
    "search": {"grid", "visited vertices", "messages (links within r_c)", "failure detected"},
}


@pytest.fixture(scope="module")
def scenes(traces):
    return {name: BUILDERS[name].replay_scene(trace) for name, trace in traces.items()}


@pytest.mark.parametrize("name", list(BUILDERS))
def test_every_family_scene_shows_its_layers_and_names_the_run(scenes, traces, name):
    scene, trace = scenes[name], traces[name]
    assert EXPECTED_GROUPS[name] <= set(scene.groups()), set(scene.groups())
    assert scene.title == f"{trace.scenario} · {scene.title.split(' · ', 1)[1].rsplit(' · ', 1)[0]} · seed {trace.seed}"
    assert scene.n_robots == trace.positions.shape[1] and scene.n_frames == len(trace.positions)
    np.testing.assert_allclose(scene.positions, trace.positions)
    legend_labels = [row["label"] for row in scene.legend]
    assert len(legend_labels) == len(set(legend_labels)) >= 2
    for view in scene.views:
        assert all(re.search(r"\[.+\]", label) for label in view.labels), view.labels  # units on every axis


def test_a_three_d_run_has_a_top_and_a_side_view(scenes):
    views = scenes["avoidance_3d"].views
    assert [v.axes for v in views] == [(0, 1), (0, 2)] and views[1].labels == ("x [m]", "z [m]")


def test_the_document_round_trips_its_arrays_and_embeds_safely(scenes):
    scene = scenes["coordination"]
    doc = scene.to_document()
    np.testing.assert_allclose(decode_array(doc["positions"]), scene.positions.astype(np.float32))
    np.testing.assert_array_equal(decode_array(doc["status"]), scene.status)
    assert json.loads(json.dumps(doc)) == doc
    page = replay_html(scene)
    data = page.split('id="replay-data">', 1)[1].split("</script>", 1)[0]
    assert "</" not in data and json.loads(data)["n_frames"] == scene.n_frames
    assert "http://" not in page and "https://" not in page  # nothing fetched


def test_encoding_keeps_nan_and_integer_types():
    values = np.array([[1.5, np.nan], [-2.0, 3.25]])
    np.testing.assert_array_equal(decode_array(encode_array(values, "f4")), values.astype(np.float32))
    assert decode_array(encode_array(np.array([3, -1]), "i4")).tolist() == [3, -1]


def test_batched_cells_equal_the_one_by_one_clip(traces):
    trace = traces["avoidance"]
    A, b = trace.arrays["cell_A"][::7].reshape(-1, *trace.arrays["cell_A"].shape[2:]), trace.arrays["cell_b"][::7].reshape(-1, trace.arrays["cell_b"].shape[-1])
    clip = avoidance_geometry.clip_region(trace)
    counts, vertices = avoidance_geometry.cell_polygons(A, b, clip)
    starts = np.concatenate([[0], np.cumsum(counts)])
    for k in range(len(A)):
        one = avoidance_geometry.cell_polygon(A[k], b[k], clip)
        batch = vertices[starts[k]:starts[k + 1]]
        assert (len(one) >= 3) == (counts[k] > 0)
        if counts[k]:
            assert np.isclose(polygon_area(batch), polygon_area(one), rtol=1e-6, atol=1e-9)


def polygon_area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_arrived_robots_have_no_cell(traces, scenes):
    trace, layer = traces["avoidance"], next(la for la in scenes["avoidance"].layers if la.group == "cells")
    arrival = trace.arrays["arrival_steps"]
    last = len(trace.positions) - 1
    drawn = set(layer.arrays["robot"][layer.arrays["offsets"][last]:].tolist())
    assert drawn == {i for i in range(len(arrival)) if not 0 <= arrival[i] <= last}


def test_a_waiting_robot_waits_for_a_robot_still_to_cross_its_next_position(traces):
    trace = traces["coordination"]
    steps = np.arange(len(trace.positions))
    status = coordination.replay_status(trace, steps)
    pairs = coordination.waits_for(trace, steps, status)
    plan, x, reach = trace.arrays["plan"], trace.arrays["progress"][..., 0], 2 * trace.metadata["radius"]
    found = [(f, i, j) for f, frame_pairs in enumerate(pairs) for i, j in frame_pairs]
    assert found, "some robot waits in this run"
    for f, i, j in found[:200]:
        assert status[f, i] == 1
        ahead = plan[x[f, j]:, j]
        assert np.min(np.linalg.norm(ahead - plan[min(x[f, i] + 1, len(plan) - 1), i], axis=1)) < reach


def test_visited_vertices_appear_at_the_frame_a_robot_first_stands_on_them(traces):
    trace = traces["search"]
    steps = np.arange(len(trace.positions))
    first = search.first_visit_frames(trace, steps)
    vertex = trace.arrays["vertex"][..., 0]
    for v in np.unique(vertex):
        assert first[v] == np.argmax((vertex == v).any(axis=1))
    assert (first[np.setdiff1d(np.arange(len(first)), vertex)] == -1).all()


def test_the_leader_frame_puts_the_leader_at_the_origin_heading_along_x():
    pos = np.array([[[1.0, 1.0], [1.0, 3.0]]])
    local = flocking.leader_frame(pos, np.array([np.pi / 2]))
    np.testing.assert_allclose(local[0], [[0.0, 0.0], [2.0, 0.0]], atol=1e-12)


def test_long_runs_are_subsampled_within_max_frames(traces):
    scene = avoidance.replay_scene(traces["avoidance"], max_frames=10)
    assert scene.n_frames <= 11 and scene.steps[-1] == len(traces["avoidance"].positions) - 1 and scene.notes
    with pytest.raises(ConfigError, match="max_frames"):
        avoidance.replay_scene(traces["avoidance"], max_frames=1)


# -- robofleet view ------------------------------------------------------------------------
def run_cli(args, capsys):
    with pytest.raises(SystemExit) as stop:
        main(args)
    out, err = capsys.readouterr()
    return stop.value.code, out, err


def test_view_writes_one_self_contained_page_of_a_run(traces, tmp_path, capsys):
    run = traces["search"].save(tmp_path / "run")
    main(["view", str(run), "--no-open"])
    page = (run / "replay.html").read_text()
    assert "replay-data" in page and "<script src" not in page and "<link" not in page
    main(["view", str(run / "trace.json"), "--no-open", "--out", str(tmp_path / "other.html")])
    assert (tmp_path / "other.html").is_file()
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize("case", ["missing", "not_a_run", "bad_rerun_name"])
def test_view_refuses_bad_input_with_one_line_and_status_2(traces, tmp_path, capsys, case):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("x")
    run = traces["search"].save(tmp_path / "run")
    args = {"missing": [str(tmp_path / "nope")], "not_a_run": [str(tmp_path / "empty")],
            "bad_rerun_name": [str(run), "--rerun", str(tmp_path / "out.txt")]}[case]
    code, _, err = run_cli(["view", *args, "--no-open"], capsys)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err


def test_view_of_a_corrupt_trace_is_a_clean_error(traces, tmp_path, capsys):
    run = traces["search"].save(tmp_path / "run")
    (run / "trace.npz").write_bytes(b"not a zip")
    code, _, err = run_cli(["view", str(run), "--no-open"], capsys)
    assert code == 2 and "trace" in err and err.count("\n") == 1


def test_locate_tells_runs_from_reproductions(tmp_path):
    (tmp_path / "summary.csv").write_text("table,a\nt,1\n")
    (tmp_path / "table.md").write_text("x")
    assert locate(tmp_path).kind == "reproduction"
    with pytest.raises(ConfigError, match="expected a run directory"):
        locate(tmp_path / "summary.csv")


def test_a_reproduction_report_embeds_its_tables_and_figures(tmp_path, capsys):
    from PIL import Image

    (tmp_path / "summary.csv").write_text("table,n\nfig,1\n")
    (tmp_path / "table.md").write_text("Results per method:\n\n| method | rate |\n|---|---:|\n| `bvc` | 0.5 |\n| buavc | 0 |\n")
    Image.new("RGB", (4, 3), "red").save(tmp_path / "fig.png")
    (tmp_path / "runs" / "sweep_a").mkdir(parents=True)
    main(["view", str(tmp_path), "--no-open"])
    page = (tmp_path / "report.html").read_text()
    assert page.count("<tr>") == 3 and "<code>bvc</code>" in page and "data:image/png;base64," in page and "sweep_a" in page
    code, _, err = run_cli(["view", str(tmp_path), "--no-open", "--rerun", str(tmp_path / "a.rrd")], capsys)
    assert code == 2 and "--rerun" in err


def test_markdown_tables_and_paragraphs():
    text = markdown_html("# Title\n\nline one\nline two\n\n| a | b |\n|---|---|\n| 1 | <2> |\n")
    assert "<h2>Title</h2>" in text and "<p>line one line two</p>" in text and "<td>&lt;2&gt;</td>" in text


def test_report_of_a_directory_without_figures_says_so(tmp_path):
    (tmp_path / "table.md").write_text("nothing")
    assert "No figures were written." in report_html(tmp_path)


def test_a_trace_of_an_unknown_family_is_refused(traces, tmp_path, capsys):
    trace = traces["search"]
    Trace("nosuch", trace.arrays, trace.events, trace.metadata, trace.results, trace.workspace).save(tmp_path / "run")
    code, _, err = run_cli(["view", str(tmp_path / "run"), "--no-open"], capsys)
    assert code == 2 and "family" in err


def test_building_a_replay_page_loads_no_plotting_library(traces, tmp_path):
    """The replay page is computed from the trace with numpy alone: a fresh process that
    loads saved traces of every family and writes their pages never imports matplotlib."""
    for name, trace in traces.items():
        trace.save(tmp_path / name)
    code = ("import sys\nfrom pathlib import Path\nfrom robofleet.core.trace import Trace\n"
            "from robofleet.viz.replay import scene_builder\nfrom robofleet.viz.replay.page import write_html\n"
            f"for run in sorted(Path({str(tmp_path)!r}).iterdir()):\n"
            "    trace = Trace.load(run)\n    write_html(scene_builder(trace.family)(trace), run / 'replay.html')\n"
            "print('matplotlib' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split()[-1] == "False"
    assert all((tmp_path / name / "replay.html").is_file() for name in traces)
