"""The scenario's ``navigation:`` block: one sub-block per stage, defaults from the stages'
own parameter blocks, and a one-line error for a flat ``liveness:`` block that names where
each of its fields belongs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

import robofleet
from robofleet.avoidance.navigation import NavigationParams
from robofleet.avoidance.navigation.params import LIVENESS_PLACES, STAGE_BLOCKS, from_mapping
from robofleet.avoidance.spec import NavigationSpec
from robofleet.avoidance.world import navigation_params
from robofleet.core.errors import ScenarioError


def test_the_scenario_defaults_are_the_stages_defaults():
    assert from_mapping(NavigationSpec().model_dump()) == NavigationParams()
    assert navigation_params(robofleet.load_scenario({"family": "avoidance"})) == NavigationParams()


def test_nested_values_reach_their_stage():
    spec = robofleet.load_scenario({"family": "avoidance", "navigation": {
        "route": {"passage_sigmas": 0.5}, "yielding": {"near": 0.9}, "right_hand": {"angle": 30.0},
        "detour": {"enabled": False, "steps": 12}, "band": {"sigmas": 3.0}}})
    params = navigation_params(spec)
    assert (params.route.passage_sigmas, params.yielding.near, params.right_hand.angle) == (0.5, 0.9, 30.0)
    assert (params.detour.enabled, params.detour.steps, params.band.sigmas) == (False, 12, 3.0)


def test_every_flat_field_has_a_place_that_exists():
    for old, place in LIVENESS_PLACES.items():
        *block, key = place.split(".")
        model = STAGE_BLOCKS[block[0]] if block else NavigationParams
        assert key in model.__dataclass_fields__, (old, place)


@pytest.mark.parametrize("old,new", [("right_hand_angle", "navigation.right_hand.angle"), ("near", "navigation.yielding.near"),
                                     ("enabled", "navigation.enabled"), ("passage_sigmas", "navigation.route.passage_sigmas")])
def test_a_liveness_block_gets_one_line_naming_the_new_place(old, new):
    with pytest.raises(ScenarioError) as info:
        robofleet.load_scenario({"family": "avoidance", "liveness": {old: 1}})
    message = str(info.value)
    assert "\n" not in message and ": liveness: expected" in message and new in message and "received" in message, message


def test_a_bad_stage_value_names_its_nested_field():
    with pytest.raises(ScenarioError, match="navigation.yielding.near: expected"):
        robofleet.load_scenario({"family": "avoidance", "navigation": {"yielding": {"near": -1}}})


def test_the_cli_names_the_file_and_exits_2_on_a_liveness_block(tmp_path):
    f = tmp_path / "old.yaml"
    f.write_text(yaml.safe_dump({"family": "avoidance", "liveness": {"enabled": False}}))
    exe = Path(sys.executable).parent / "robofleet"
    proc = subprocess.run([str(exe), "validate", str(f)], capture_output=True, text=True)
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert len(lines) == 1 and str(f) in lines[0] and "navigation.enabled" in lines[0], proc.stderr
