"""The family contract for flocking: the seed rule, the guarantees report, ``success``,
the documented results and the conformance checker."""

import ast
import json
from pathlib import Path

import numpy as np
import pytest

import robofleet
import robofleet.viz.flocking
from robofleet.core.errors import ConfigError, ScenarioError
from robofleet.core.family import Guarantee
from robofleet.flocking.family import FAMILY
from robofleet.flocking.metrics import formed_and_kept
from robofleet.flocking.simulation import simulate
from robofleet.testing import check_family, check_scenario


def short(name="flocking/wedge_async", **overrides):
    return robofleet.load_scenario(name, overrides={"duration": 30, **overrides})


def by_reference(report):
    return {g.reference: g for g in report}


def test_seed_none_draws_a_seed_that_replays_the_run():
    spec = short(**{"algorithm.kind": "randomized", "pattern.kind": "random"})
    first = simulate(spec, seed=None)
    assert isinstance(first.seed, int) and 0 <= first.seed < 2**63
    again = simulate(spec, seed=first.seed)
    for key, value in first.arrays.items():
        if key != "step_seconds":
            assert np.array_equal(value, again.arrays[key], equal_nan=True), key
    assert first.events == again.events
    assert json.dumps(first.results, default=str) == json.dumps(again.results, default=str)


@pytest.mark.parametrize("seed", [-1, 1.5, "3", True, 2**63, np.random.default_rng(0)])
def test_refused_seeds_are_one_line_config_errors(seed):
    with pytest.raises(ConfigError, match=r"^seed: expected a non-negative integer below 2\*\*63 or None"):
        simulate(short(), seed=seed)


def test_the_guarantees_of_a_shipped_scenario_all_hold():
    report = FAMILY.check(robofleet.load_scenario("flocking/wedge_async"))
    assert all(isinstance(g, Guarantee) for g in report)
    assert {"A1", "A2", "A3", "Sec. 4.1, item 2", "Sec. 4.1, item 3", "Sec. 3.2, (1)", "Sec. 3.2, (2)", "Sec. 3.2, (3)"} <= set(by_reference(report))
    assert all(g.holds for g in report), [g.line() for g in report if not g.holds]


def test_a_pattern_with_two_axis_points_reports_no_for_the_basic_algorithm():
    spec = robofleet.load_scenario({"family": "flocking", "pattern": {"kind": "points", "points": [[-40, 0], [-90, 0]]},
                                    "algorithm": {"kind": "basic"}, "checks": {"pattern": "ignore"}})
    report = by_reference(FAMILY.check(spec))
    assert not report["Sec. 4.1, item 3"].holds and "2 points on the axis" in report["Sec. 4.1, item 3"].line()
    assert not report["Secs. 4.1, 6.1-6.4"].holds
    assert report["Sec. 4.1, item 2"].holds


def test_a_non_lb_symmetric_pattern_reports_no_and_randomized_can_still_form_it():
    spec = robofleet.load_scenario("flocking/randomized_asymmetric")
    report = by_reference(FAMILY.check(spec))
    assert not report["Sec. 4.1, item 2"].holds
    assert report["Secs. 4.1, 6.1-6.4"].holds


def test_a_leader_faster_than_the_slowest_follower_violates_conditions_1_and_2():
    spec = robofleet.load_scenario({"family": "flocking", "pattern": {"kind": "line"}, "followers": {"speeds": [1.0, 2.0, 3.0, 4.0]},
                                    "leader": {"kind": "random_turns", "speed": 1.5, "turn_rate": 0.0},
                                    "checks": {"conditions": "ignore"}})
    report = by_reference(FAMILY.check(spec))
    assert not report["Sec. 3.2, (1)"].holds and "v_L = 1.5 ≥ slowest v_f = 1" in report["Sec. 3.2, (1)"].line()
    assert not report["Sec. 3.2, (2)"].holds
    assert report["Sec. 3.2, (3)"].holds


def test_a_minimum_move_no_cycle_allows_violates_a2_and_the_run_is_refused():
    spec = robofleet.load_scenario({"family": "flocking", "pattern": {"kind": "line"},
                                    "followers": {"speed_min": 0.5, "speed_max": 0.6},
                                    "scheduler": {"kind": "async", "cycle_min": 0.5, "min_move": 1.0}, "duration": 10})
    a2 = by_reference(FAMILY.check(spec))["A2"]
    assert not a2.holds and a2.line().startswith("every Move covers at least δ_f (A2): no")
    with pytest.raises(ScenarioError, match="min_move"):
        simulate(spec, seed=1)


def test_success_means_the_formation_was_formed_and_kept():
    formed = simulate(robofleet.load_scenario("flocking/wedge_fsync_straight"), seed=1)
    assert formed.summary()["success"] is True
    assert formed_and_kept(formed.arrays["delta_e"], formed.results["xi"])
    not_yet = simulate(short(duration=20), seed=1)      # 20 moves from random starts 512 units apart
    assert not_yet.results["success"] is False and not_yet.results["delta_e_final"] > not_yet.results["xi"]
    # formed at the last sample only is not kept
    de = np.r_[np.full(95, 50.0), np.full(4, 50.0), 1.0]
    assert not formed_and_kept(de, 5.0) and formed_and_kept(np.r_[de[:-10], np.ones(10)], 5.0)


def test_every_summary_key_is_documented_including_the_reflection_ones():
    for name in ("flocking/wedge_async", "flocking/randomized_asymmetric"):
        summary = simulate(short(name), seed=2).summary()
        undocumented = [k for k in list(summary)[7:] if k not in FAMILY.results]
        assert not undocumented, (name, undocumented)
    assert "delta_m_final" in simulate(short("flocking/randomized_asymmetric"), seed=2).summary()


def test_the_trace_carries_what_the_figures_need_and_viz_imports_only_core():
    trace = simulate(short(), seed=3)
    m = trace.results["n_followers"]
    assert trace.arrays["estimated_target"].shape == (31, m, 2)
    assert trace.metadata["leader_index"] == 0 and trace.metadata["scenario"] == "wedge_async"
    tree = ast.parse(Path(robofleet.viz.flocking.__file__).read_text())
    relative = {("." * node.level) + (node.module or "") for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.level}
    assert relative <= {"..core.trace", ".animation"}, relative


def test_check_family_checks_every_shipped_flocking_scenario():
    """The family-level entry point names and checks every shipped flocking scenario (each
    one's full check, figures included, is ``tests/conformance/test_scenarios.py``)."""
    checked = check_family("flocking", steps=2, figures=False)
    assert checked == [e.name for e in robofleet.scenarios.list() if e.family == "flocking"] and len(checked) == 13


def test_conformance_of_a_file_pattern_scenario(tmp_path):
    (tmp_path / "p.csv").write_text("-40,20\n-40,-20\n-80,0\n")
    (tmp_path / "s.yaml").write_text("family: flocking\npattern: {kind: file, path: p.csv}\nduration: 5\n")
    check_scenario(str(tmp_path / "s.yaml"), steps=4, figures=False)
