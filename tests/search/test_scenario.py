"""Scenario files: bad input gives one-line errors; the seed rule; determinism by seed; CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robofleet import load_scenario, simulate
from robofleet.core.errors import ConfigError, ScenarioError
from robofleet.search import check

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
        main(["check", str(path)])
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
    assert trace.positions.shape == (n + 1, 3, 2) and trace.positions.dtype == np.float64
    assert trace.arrays["time"].shape == (n + 1, 3, 1)
    assert np.all(np.diff(trace.arrays["time"][:, 0, 0]) > 0)
    trace.save(tmp_path / "t")
    json.loads((tmp_path / "t" / "trace.json").read_text())
    summary = trace.summary()
    assert summary["found_targets"] == 4 and summary["collisions"] == 0


def test_shipped_fig7_scenario_holds_every_assumption():
    spec = load_scenario("search/fig7")
    assert spec.assumption_report().complete_search
    assert len(spec.targets) == 9


def test_seed_none_draws_records_and_replays():
    """The seed rule: seed=None draws a seed, records it, and trace.seed replays the run."""
    spec = small_spec(**{"robots.count": 4, "algorithm": "ru", "require_guarantee": False})
    drawn = simulate(spec, seed=None)
    assert isinstance(drawn.seed, int) and drawn.summary()["seed"] == drawn.seed
    again = simulate(spec, seed=drawn.seed)
    for key in ("positions", "vertex", "time"):
        np.testing.assert_array_equal(drawn.arrays[key], again.arrays[key])
    assert drawn.events == again.events and drawn.results == again.results


@pytest.mark.parametrize("seed", [-1, 2**63, 1.5, "7", True, np.random.default_rng(0)])
def test_refused_seeds_are_one_line_config_errors(seed):
    with pytest.raises(ConfigError) as err:
        simulate(small_spec(), seed=seed)
    assert "\n" not in str(err.value) and "seed" in str(err.value)


def test_workspace_block_is_the_shared_vocabulary():
    """``rectangle`` is ``bounds``; obstacles may be boxes or bare vertex lists; Assumption 2.1
    (obstacles inside the area, non-overlapping) is enforced."""
    box = {"center": [2.4, 2.5], "size": [1.2, 1.4]}
    a = small_spec(workspace={"bounds": [0, 0, 8, 7], "corner_radius": 1.5, "obstacles": [box]})
    b = small_spec(workspace={"rectangle": [0, 0, 8, 7], "corner_radius": 1.5,
                                    "obstacles": [[[1.8, 1.8], [3.0, 1.8], [3.0, 3.2], [1.8, 3.2]]]})
    np.testing.assert_allclose(a.built_grid().points, b.built_grid().points)
    assert (a.built_grid().accessible == b.built_grid().accessible).all()
    for obstacles, text in (([[[7.0, 6.0], [9.0, 6.0], [9.0, 8.0]]], "inside the area"),
                            ([box, {"center": [2.8, 2.8], "size": [1.0, 1.0]}], "non-overlapping")):
        with pytest.raises(ScenarioError, match=text):
            small_spec(**{"workspace.obstacles": obstacles})


def test_success_only_when_every_target_is_found_without_collision():
    spec = small_spec(**{"robots.count": 9, "algorithm": "ru", "require_guarantee": False})
    traces = [simulate(spec, seed=s) for s in range(6)]
    for t in traces:
        r = t.results
        assert r["success"] == (r["completed"] and r["found_targets"] == r["n_targets"] and r["collisions"] == 0
                                and r["obstacle_collisions"] == 0)
    assert not all(t.results["success"] for t in traces)  # RU collides in a crowd
    cut = simulate(small_spec(max_steps=2), seed=1)
    assert not cut.results["completed"] and not cut.results["success"]


def test_check_reports_the_papers_conditions():
    """FAMILY.check: every condition holds on the Fig. 7 scenario; a violated one is named,
    and the consequences that depend on it no longer hold."""
    fig7 = {g.reference: g for g in check(load_scenario("search/fig7"))}
    for ref in ("Assumption 2.1", "Assumption 2.2", "Section 2", "Assumption 2.4", "Assumption 2.5", "Assumption 3.1.1",
                "Assumption 3.1.2", "Assumption 3.1.3", "Table 1", "Section 3", "Theorem 4.1", "Theorem 4.1, Section 3"):
        assert fig7[ref].holds, fig7[ref].line()
    short = {g.reference: g for g in check(small_spec(**{"ranges.r_so": 1.0, "require_guarantee": False}))}
    assert not short["Assumption 2.4"].holds and not short["Table 1"].holds
    assert not short["Section 2, Assumptions 2.4-2.5"].holds and not short["Theorem 4.1, Section 3"].holds
    ru = {g.reference: g for g in check(small_spec(algorithm="ru", require_guarantee=False))}
    assert not ru["Section 4.2, steps 4-5"].holds and not ru["Section 2, Assumptions 2.4-2.5"].holds
    hexagonal = {g.reference: g for g in check(small_spec(**{"grid.kind": "hexagonal", "require_guarantee": False}))}
    assert not hexagonal["Section 3"].holds and not hexagonal["Theorem 4.1, Section 3"].holds
    assert all("\n" not in g.line() for g in fig7.values())
