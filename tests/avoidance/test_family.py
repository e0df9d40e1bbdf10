"""The avoidance family's contract: seed rule, results, guarantees, one team representation."""

import numpy as np
import pytest

import robofleet
from robofleet.avoidance.family import FAMILY
from robofleet.avoidance.guarantees import check
from robofleet.core import metrics
from robofleet.core.errors import ConfigError
from robofleet.core.trace import CORE_SUMMARY_KEYS
from robofleet.testing import check_scenario


def short(name, **overrides):
    return robofleet.load_scenario(name, {"max_steps": 40, **overrides})


def assert_same_run(a, b):
    assert sorted(a.arrays) == sorted(b.arrays)
    for key in a.arrays:
        if not key.endswith("_seconds"):
            np.testing.assert_array_equal(a.arrays[key], b.arrays[key])
    assert a.events == b.events


@pytest.mark.parametrize("name", ["avoidance/three_boxes", "avoidance/diff_drive"])
def test_seed_none_draws_a_seed_that_replays_the_run(name):
    spec = short(name)
    drawn = robofleet.simulate(spec, seed=None)
    assert isinstance(drawn.seed, int) and drawn.summary()["seed"] == drawn.seed
    assert_same_run(drawn, robofleet.simulate(spec, seed=drawn.seed))


@pytest.mark.parametrize("seed", ["abc", -1, 1.5, True, 2**63])
def test_refused_seeds_give_one_line_config_errors(seed):
    spec = short("avoidance/circle_swap")
    with pytest.raises(ConfigError) as info:
        FAMILY.simulate(spec, seed=seed)
    assert "\n" not in str(info.value) and "seed" in str(info.value)


def test_summary_is_led_by_the_core_keys_and_every_other_key_is_documented():
    summary = robofleet.simulate(short("avoidance/three_boxes"), seed=2).summary()
    assert list(summary)[: len(CORE_SUMMARY_KEYS)] == list(CORE_SUMMARY_KEYS)
    assert set(summary) - set(CORE_SUMMARY_KEYS) == set(FAMILY.results)


def test_collision_frequencies_count_true_contacts():
    """BVC under heavy noise collides; the rates are the contact counts over all couples."""
    spec = robofleet.load_scenario("avoidance/three_boxes", {"method": "bvc", "robots.sigma": 0.3, "max_steps": 150})
    trace = robofleet.simulate(spec, seed=4)
    s = trace.summary()
    pos, r = trace.positions, spec.robots.radius
    contacts, _ = metrics.pair_contacts(pos, r)
    obstacle_hits, _ = metrics.obstacle_contacts(pos, r, trace.workspace)
    n, frames = pos.shape[1], len(pos)
    assert s["pair_step_rate"] == len(contacts) / (n * (n - 1) / 2 * frames)
    assert s["pair_rate"] == len({(i, j) for _, i, j in contacts}) / (n * (n - 1) / 2)
    assert s["obstacle_step_rate"] == len(obstacle_hits) / (n * frames)
    assert s["run_collided"] == bool(len(contacts) or len(obstacle_hits)) and s["run_collided"]
    assert not s["success"]


def test_box_contacts_in_3d_fail_the_run():
    """A 3-D box the quadrotors must cross: contacts are counted and the run is no success."""
    spec = robofleet.load_scenario("avoidance/quadrotors_3d", {"max_steps": 3, "space3d.boxes": [{"center": [4.0, 0.0, 1.2], "size": [0.3, 0.3, 0.3]}]})
    s = robofleet.simulate(spec, seed=0).summary()
    assert s["obstacle_collisions"] == 1 and s["min_obstacle_distance"] < 0.2
    assert s["obstacle_step_rate"] > 0 and s["run_collided"] and not s["success"]


def test_guarantees_hold_on_the_authors_setup():
    report = check(robofleet.load_scenario("avoidance/three_boxes"))
    assert [g.holds for g in report] == [True] * 5
    assert "δ = 0.1" in report[-1].line()


def test_guarantees_say_no_when_robots_start_closer_than_the_chance_clearance():
    """Two robots 0.45 m apart are valid (≥ 2 r_s) but closer than 2 (r_s + Φ⁻¹(√(1 − δ)) σ)."""
    spec = robofleet.load_scenario({"robots": {"n": 2, "sigma": 0.1, "layout": {"kind": "explicit", "starts": [[0, 0], [0.45, 0]], "goals": [[2, 2], [-2, -2]]}}})
    report = {g.name: g for g in check(spec)}
    premise = report["robots start inside their own B-UAVC"]
    assert not premise.holds and "): no — 2 of 2 robots start outside their cell" in premise.line()
    assert not report["collision probability ≤ δ per pair and step"].holds
    assert "robots start inside their own B-UAVC" in report["collision probability ≤ δ per pair and step"].detail
    far = robofleet.load_scenario({"robots": {"n": 2, "sigma": 0.1, "layout": {"kind": "explicit", "starts": [[0, 0], [1.0, 0]], "goals": [[2, 2], [-2, -2]]}}})
    assert {g.name: g for g in check(far)}["robots start inside their own B-UAVC"].holds


@pytest.mark.parametrize("method", ["bvc", "bvc_inflated", "orca"])
def test_methods_without_the_chance_constraint_carry_no_bound(method):
    report = check(robofleet.load_scenario("avoidance/circle_swap", {"method": method}))
    assert not report[0].holds and method in report[0].detail
    assert not report[-1].holds


def test_models_without_a_containment_proof_carry_no_bound():
    report = {g.name: g for g in check(robofleet.load_scenario("avoidance/diff_drive"))}
    assert not report["controllers provably keep every robot inside its cell"].holds
    assert report["chance-constrained cells (B-UAVC)"].holds
    assert {g.name: g for g in check(robofleet.load_scenario("avoidance/double_integrator"))}["collision probability ≤ δ per pair and step"].holds


def test_a_shipped_scenario_passes_the_conformance_checks():
    check_scenario("avoidance/circle_swap", steps=4, figures=False)
