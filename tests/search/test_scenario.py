"""Scenario files: bad input gives one-line errors; determinism by seed; CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robofleet import load_scenario, simulate
from robofleet.core.errors import ScenarioError
from robofleet.scenarios import shipped_scenario

from .helpers import small_spec


@pytest.mark.parametrize("overrides, field, text", [
    ({"grid.a": 0.0}, "grid.a", "positive edge length"),
    ({"grid.a": -1.0}, "grid.a", "positive edge length"),
    ({"ranges.r_so": 1.0}, "ranges.r_so", "Assumption 2.4"),
    ({"ranges.r_c": 1.5}, "ranges.r_c", "Assumption 2.5"),
    ({"ranges.r_st": 1.0}, "ranges.r_st", "Assumption 3.1.1"),
    ({"grid.kind": "square", "situation": 2}, "grid.kind", "triangular"),
    ({"targets": [[2.4, 2.4]]}, "targets.0", "outside every obstacle"),
    ({"targets": [[20.0, 2.0]]}, "targets.0", "inside the area"),
    ({"robots": {"starts": [[1.0, 1.0]]}}, "robots.starts.0", "a grid vertex"),
    ({"robots": {"starts": [[2.31, 2.042]]}}, "robots.starts.0", "accessible vertex"),
    ({"robots": {"starts": [[3.31, 0.31], [3.31, 0.31]]}}, "robots.starts", "different vertices"),
    ({"robots": {"count": 500}}, "robots.count", "border vertices"),
    ({"failures": [{"robot": 7, "step": 1}]}, "failures.0.robot", "robot index"),
    ({"grid.kind": "pentagonal"}, "grid.kind", "triangular"),
    ({"algorithm": "lfp", "situation": 2, "require_guarantee": False}, "algorithm", "situation 2"),
    ({"bogus": 1}, "bogus", "unknown field"),
    ({"workspace": {"rectangle": [0, 0, 0.2, 0.2]}, "targets": [[0.1, 0.1]], "robots": {"count": 1}}, "grid.a", "at least one grid vertex"),
    ({"workspace.corner_radius": 5.0}, "workspace.corner_radius", "half the rectangle"),
])
def test_bad_input_is_one_clear_line(overrides, field, text):
    with pytest.raises(ScenarioError) as err:
        small_spec(**overrides)
    msg = str(err.value)
    assert "\n" not in msg and field in msg and text in msg, msg


def test_ranges_violating_assumptions_are_fine_without_guarantee():
    spec = small_spec(**{"ranges.r_so": 1.0, "require_guarantee": False})
    assert [c.name for c in spec.assumption_report().failed()] == ["2.4"]
    simulate(spec, seed=0)


def test_error_names_the_file(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("family: search\nworkspace: {rectangle: [0, 0, 5, 5]}\ngrid: {a: 0}\nrobots: {count: 1}\ntargets: [[1, 1]]\n")
    with pytest.raises(ScenarioError, match=r"bad\.yaml: grid\.a: expected a positive edge length"):
        load_scenario(path)


def test_cli_exits_2_on_bad_file(tmp_path):
    from robofleet.cli.main import main

    path = tmp_path / "bad.yaml"
    path.write_text("family: search\nworkspace: {rectangle: [0, 0, 5, 5]}\ngrid: {a: -2}\nrobots: {count: 1}\ntargets: [[1, 1]]\n")
    with pytest.raises(SystemExit) as exit_info:
        main(["search-check", str(path)])
    assert exit_info.value.code == 2


@pytest.mark.parametrize("algorithm", ["proposed", "rule1", "ru", "lfp"])
def test_same_seed_same_trace(algorithm):
    spec = small_spec(**{"robots.count": 4, "algorithm": algorithm, "require_guarantee": False})
    a, b, c = simulate(spec, seed=11), simulate(spec, seed=11), simulate(spec, seed=12)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.results == b.results and a.events == b.events
    assert not (a.positions.shape == c.positions.shape and np.array_equal(a.positions, c.positions))


def test_trace_round_trip_and_shapes(tmp_path):
    spec = small_spec(**{"robots.count": 3})
    trace = simulate(spec, seed=4)
    n = trace.metadata["n_steps"]
    assert trace.positions.shape == (n, 3, 2) and trace.positions.dtype == np.float64
    assert trace.arrays["time"].shape == (n, 3, 1)
    assert np.all(np.diff(trace.arrays["time"][:, 0, 0]) > 0)
    trace.save(tmp_path / "t")
    json.loads((tmp_path / "t" / "trace.json").read_text())
    summary = trace.summary()
    assert summary["found_targets"] == 4 and summary["collisions"] == 0


def test_shipped_fig7_scenario_holds_every_assumption():
    spec = load_scenario(shipped_scenario("search", "fig7.yaml"))
    assert spec.assumption_report().complete_search
    assert len(spec.targets) == 9
