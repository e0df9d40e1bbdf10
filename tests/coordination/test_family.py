"""The family contract for coordination: spec, seed rule, the recorded loop, guarantees,
plan files read at validation, conformance."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from pydantic import ValidationError

from coordination_instances import fig2_example
from robofleet import load_scenario, simulate
from robofleet.core.config import scenario_error_from
from robofleet.core.errors import ConfigError, ScenarioError
from robofleet.coordination.family import FAMILY
from robofleet.coordination.guarantees import check
from robofleet.coordination.instance import prepare_instance
from robofleet.coordination.plan_execution import Variant
from robofleet.coordination.simulation import make_executor
from robofleet.coordination.spec import Spec
from robofleet.coordination.trajectories import save_trajectories
from robofleet.testing import check_scenario

FIG2 = "coordination/fig2_three_robots"
OWN_MAP = "family: coordination\nworkspace: {bounds: [[-20,-20],[20,-20],[20,20],[-20,20]]}\n" \
          "robots: {placement: explicit, radius: 1.0, starts: [[-10,0],[-1,-6],[3,-3]], goals: [[10,0],[-1,10],[-5,9]]}\n"


# ---------------------------------------------------------------- seeds
def test_seed_none_draws_a_seed_that_replays_the_run():
    spec = load_scenario("coordination/x_corridor_5_tff", {"simulation.max_steps": 400})
    drawn = simulate(spec, seed=None)
    assert isinstance(drawn.seed, int) and drawn.metadata["seed"] == drawn.seed
    again = simulate(spec, seed=drawn.seed)
    for key, array in drawn.arrays.items():
        if not key.endswith("_seconds"):
            assert np.array_equal(array, again.arrays[key]), key
    assert drawn.events == again.events


@pytest.mark.parametrize("seed", [-1, 1.5, "7", True, np.random.default_rng(0), 2**63])
def test_refused_seeds_are_config_errors(seed):
    spec = load_scenario(FIG2)
    with pytest.raises(ConfigError, match=r"^seed: expected a non-negative integer below 2\*\*63 or None"):
        simulate(spec, seed=seed)


# ---------------------------------------------------------------- the recorded loop
@pytest.mark.parametrize("method, check_on", [("rmtrack", False), ("tff", True), ("tfa", False)])
def test_recorded_run_equals_the_executor_run(method, check_on):
    """simulate drives PlanExecutor through the recorder: the same progress, waiting states,
    events and arrivals as the executor's own loop."""
    spec = load_scenario("coordination/x_corridor_5_tff", {"policy.method": method, "policy.deadlock_check": check_on})
    trace = simulate(spec, seed=3, progress=True)
    workspace = spec.build_workspace()
    run = make_executor(spec, prepare_instance(spec, 3, workspace), workspace, Variant(spec.policy.method, check_on)).run(3, spec.simulation.max_steps)
    assert np.array_equal(trace.arrays["progress"][..., 0], run.progress)
    assert np.array_equal(trace.arrays["waiting"][..., 0], run.waiting)
    assert np.array_equal(trace.arrays["arrival_steps"], run.arrival_steps)
    assert [e for e in trace.events if e["kind"] != "arrived"] == run.events
    assert trace.metadata["n_steps"] == run.n_steps and trace.results["flips"] == run.flips
    assert trace.results["finished"] == run.finished and trace.summary()["success"]


def test_budget_spent_ends_with_a_timeout_event():
    trace = simulate(load_scenario("coordination/x_corridor_5_tff", {"simulation.max_steps": 50}), seed=1)
    assert trace.metadata["n_steps"] == 50 and trace.positions.shape == (51, 5, 2)
    assert trace.events[-1] == {"step": 50, "kind": "timeout"}
    assert not trace.results["finished"] and not trace.summary()["success"] and np.isnan(trace.results["makespan"])


def test_summary_keys_are_documented():
    summary = simulate(load_scenario(FIG2), seed=0).summary()
    assert [k for k in summary if k not in FAMILY.results] == ["family", "scenario", "seed", "success", "n_robots", "n_steps", "wall_seconds"]


def test_conformance_of_the_three_robot_example():
    check_scenario(FIG2, steps=5)


# ---------------------------------------------------------------- guarantees
def test_fig2_guarantees_non_conflicting_but_overlapping_segments():
    report = {g.reference: g for g in check(load_scenario(FIG2))}
    assert report["Definition 4"].holds and not report["Theorem 4"].holds
    assert report["Definition 4"].line().startswith("non-conflicting (Definition 4): yes — deadlock ⇔ cycle")
    assert report["Theorem 4"].line().startswith("disjoint collision segments (Theorem 4): no — 3 overlaps")
    assert "robot 0: steps" in report["Theorem 4"].line()


def test_guarantees_of_a_drawn_instance_name_the_seed():
    spec = load_scenario("coordination/x_corridor_20", {"robots.count": 5, "robots.instance_seed": None})
    lines = [g.line() for g in check(spec, seed=4)]
    assert all("instance of run seed 4" in line for line in lines)


# ---------------------------------------------------------------- workspace block
def test_own_map_bounds_select_no_preset_and_regions_carry_probabilities():
    spec = load_scenario({"family": "coordination", "workspace": {"bounds": [0, 0, 100, 50], "regions": [
        {"name": "mud", "vertices": [[0, 0], [10, 0], [10, 10]], "probability": 0.5}]},
        "robots": {"placement": "explicit", "starts": [[20, 20]], "goals": [[80, 20]], "radius": 2}})
    ws = spec.build_workspace()
    assert spec.workspace.preset is None and ws.region("mud").attributes == {"probability": 0.5}
    preset = load_scenario({"family": "coordination", "robots": {"count": 2}}).build_workspace()
    assert preset.region("disturbance").attributes == {"probability": 0.85}


@pytest.mark.parametrize("name", ["coordination/fig2_three_robots", "coordination/x_corridor_20"])
def test_a_dumped_spec_validates_again(name):
    dumped = load_scenario(name).model_dump(mode="json")
    assert Spec.model_validate(dumped).model_dump(mode="json") == dumped


@pytest.mark.parametrize("workspace, match", [
    ({"preset": "x_corridor", "bounds": [0, 0, 10, 10]}, "workspace.preset: expected null when bounds are given"),
    ({"preset": None}, "workspace.bounds: expected the map's bounds when preset is null"),
    ({"regions": [{"name": "r", "vertices": [[0, 0], [1, 0], [0, 1]]}]}, r"workspace.regions.0.probability: expected this required field"),
    ({"regions": [{"name": "r", "vertices": [[0, 0], [1, 0], [0, 1]], "probability": 1.0}]}, "probability"),
])
def test_bad_workspaces(workspace, match):
    with pytest.raises(ScenarioError, match=match):
        load_scenario({"family": "coordination", "workspace": workspace, "robots": {"count": 2}})


# ---------------------------------------------------------------- plan files read at validation
def scenario_file(tmp_path, plan_text: str, name: str = "plan.csv"):
    (tmp_path / name).write_text(plan_text)
    path = tmp_path / "s.yaml"
    path.write_text(OWN_MAP + f"trajectories: {name}\n")
    return path


def validate_with_source(path) -> Spec:
    """Validation as the scenario loader runs it when it names the file (context source)."""
    try:
        return Spec.model_validate(yaml.safe_load(path.read_text()), context={"source": str(path)})
    except ValidationError as exc:
        raise scenario_error_from(exc, str(path)) from None


@pytest.mark.parametrize("text, match", [
    ("", r"s.yaml: trajectories: .*plan.csv: expected a CSV file with header robot,step,x,y .*received 'an empty file'$"),
    ("robot,step,x,y\n", r"plan.csv: expected at least one row robot,step,x,y below the header"),
    ("robot,step,x,y\n0,0,0,0\n0,1,1,abc\n", r"plan.csv: row 3, column y: expected a finite number, received 'abc'$"),
    ("robot,step,x,y\n0,0,0,0\n0,1.5,1,1\n", r"plan.csv: row 3, column step: expected a non-negative integer, received '1.5'"),
    ("robot,step,x,y\n0,0,0,0\n0,1\n", r"plan.csv: row 3: expected 4 cells robot,step,x,y"),
    ("robot,step,x,y\n0,0,0,0\n", r"trajectories: expected 3 trajectories \(one per robot\)"),
])
def test_bad_plan_file_fails_validation_on_one_line(tmp_path, text, match):
    path = scenario_file(tmp_path, text)
    with pytest.raises(ScenarioError, match=match) as info:
        validate_with_source(path)
    assert "\n" not in str(info.value)
    with pytest.raises(ScenarioError, match=match.removeprefix(r"s.yaml: trajectories: .*")):  # and at run time
        simulate(load_scenario(path), seed=0)


def test_absolute_plan_path_is_read_by_load_scenario(tmp_path):
    (tmp_path / "plan.csv").write_text("")
    data = {"family": "coordination", "workspace": {"bounds": [[-20, -20], [20, -20], [20, 20], [-20, 20]]},
            "robots": {"placement": "explicit", "radius": 1.0, "starts": [[-10, 0]], "goals": [[10, 0]]},
            "trajectories": str(tmp_path / "plan.csv")}
    with pytest.raises(ScenarioError, match=r"^<mapping>: trajectories: .*plan.csv: expected a CSV file"):
        load_scenario(data)


def test_good_plan_file_validates(tmp_path):
    save_trajectories(fig2_example(), tmp_path / "plan.csv")
    path = tmp_path / "s.yaml"
    path.write_text(OWN_MAP + "trajectories: plan.csv\n")
    assert validate_with_source(path).trajectories == "plan.csv"
    assert simulate(load_scenario(path), seed=1).results["finished"]
