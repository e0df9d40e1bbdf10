"""Plans from files and from the planner; the bad inputs of the issue; scenario files; CLI."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from coordination_instances import fig2_example, line
from robofleet import load_scenario, simulate
from robofleet.cli.main import app
from robofleet.core.errors import InfeasibleError, ScenarioError
from robofleet.core.workspace import Workspace
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.maps import x_corridor_workspace
from robofleet.coordination.planner import PlannerSettings, plan_prioritized
from robofleet.coordination.guarantees import check_theory, conflicts
from robofleet.coordination.trajectories import load_trajectories, make_trajectories, save_trajectories

SETTINGS = PlannerSettings(radius=15.0, speed=50.0, dt=0.1)


# ---------------------------------------------------------------- trajectories from files
@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_trajectories_round_trip(tmp_path, suffix):
    traj = fig2_example()
    loaded = load_trajectories(save_trajectories(traj, tmp_path / f"plan{suffix}"), traj.radius, traj.dt)
    assert np.array_equal(loaded.lengths, traj.lengths)
    assert np.allclose(loaded.positions, traj.positions)


def test_npz_with_one_array_per_robot(tmp_path):
    np.savez(tmp_path / "p.npz", robot_0=line((0, 0), (5, 0), 0.5), robot_1=line((0, 5), (5, 5), 0.5, 3))
    traj = load_trajectories(tmp_path / "p.npz", 1.0, 0.1)
    assert traj.n_robots == 2 and traj.lengths.tolist() == [10, 13]


def test_parking_is_trimmed():
    traj = make_trajectories([np.array([[0, 0], [1, 0], [2, 0], [2, 0], [2, 0]])], 0.5, 0.1)
    assert traj.lengths.tolist() == [2]


@pytest.mark.parametrize("bad, match", [
    (np.zeros((5, 3)), r"trajectories\[0\]: expected an array shaped \(K\+1, 2\)"),
    (np.array([[0.0, 0.0], [np.nan, 1.0]]), r"trajectories\[0\]: expected finite coordinates"),
    (np.array([[0.0, 0.0], [np.inf, 1.0]]), r"finite coordinates"),
])
def test_bad_trajectories(bad, match):
    with pytest.raises(ScenarioError, match=match):
        make_trajectories([bad], 1.0, 0.1)


@pytest.mark.parametrize("radius", [0.0, -1.0, float("nan")])
def test_bad_radius(radius):
    with pytest.raises(ScenarioError, match="robots.radius: expected a number > 0"):
        make_trajectories([np.zeros((3, 2))], radius, 0.1)


def test_bad_csv_names_the_file_and_field(tmp_path):
    path = tmp_path / "plan.csv"
    path.write_text("robot,step,x,y\n0,0,0,0\n0,2,1,1\n")
    with pytest.raises(ScenarioError, match=r"plan.csv: robot 0.step: expected consecutive steps"):
        load_trajectories(path, 1.0, 0.1)
    path.write_text("robot,k,x,y\n0,0,0,0\n")
    with pytest.raises(ScenarioError, match="header: expected columns robot,step,x,y"):
        load_trajectories(path, 1.0, 0.1)
    with pytest.raises(ScenarioError, match="expected a .csv or .npz file"):
        load_trajectories(tmp_path / "plan.txt", 1.0, 0.1)


# ---------------------------------------------------------------- planner
def corridor_instance():
    ws = Workspace.rectangle(0, 0, 600, 300)
    starts = np.array([[60.0, 60.0], [540.0, 240.0], [60.0, 240.0]])
    goals = np.array([[540.0, 60.0], [150.0, 150.0], [450.0, 240.0]])
    return ws, starts, goals


def test_planner_gives_collision_free_plan_ending_at_goals():
    ws, starts, goals = corridor_instance()
    traj = plan_prioritized(ws, starts, goals, SETTINGS)
    assert np.allclose(traj.starts, starts) and np.allclose(traj.goals, goals)
    step = np.linalg.norm(np.diff(traj.positions, axis=1), axis=-1)
    assert step.max() <= SETTINGS.speed * SETTINGS.dt + 1e-9
    plan_time = traj.in_plan_time(int(traj.lengths.max()) + 1)
    d = np.linalg.norm(plan_time[:, :, None] - plan_time[:, None], axis=-1)
    d[:, np.arange(3), np.arange(3)] = np.inf
    assert d.min() >= 2 * SETTINGS.radius
    assert np.all(ws.clearance(traj.positions.reshape(-1, 2)) >= SETTINGS.radius - 1e-9)
    build_coordination_space(traj)  # labels defined (raises on a colliding plan)


def test_start_inside_an_obstacle_is_a_scenario_error():
    ws = Workspace.rectangle(0, 0, 600, 300, obstacles=[np.array([[250, 0], [350, 0], [350, 200], [250, 200]], float)])
    with pytest.raises(ScenarioError, match=r"robots.starts\[0\]: expected a point inside the free space"):
        plan_prioritized(ws, np.array([[300.0, 100.0]]), np.array([[500.0, 250.0]]), SETTINGS)


def test_unreachable_goal_is_an_infeasible_error():
    wall = np.array([[290, 0], [310, 0], [310, 300], [290, 300]], float)
    ws = Workspace.rectangle(0, 0, 600, 300, obstacles=[wall])
    with pytest.raises(InfeasibleError, match=r"robots\[0\]"):
        plan_prioritized(ws, np.array([[100.0, 150.0]]), np.array([[500.0, 150.0]]), SETTINGS)


def test_invalid_infrastructure_is_reported():
    """Robot 1 parks in the only passage: no path of robot 0 avoids its goal disc."""
    ws = Workspace.rectangle(0, 0, 900, 60)
    with pytest.raises(InfeasibleError, match="valid infrastructure"):
        plan_prioritized(ws, np.array([[40.0, 30.0], [800.0, 30.0]]), np.array([[860.0, 30.0], [450.0, 30.0]]), SETTINGS)


def test_x_corridor_plan_and_theory_checks():
    from robofleet.coordination.maps import sample_flow_instance

    ws = x_corridor_workspace()
    starts, goals = sample_flow_instance(ws, 6, 15.0, np.random.default_rng(4))
    traj = plan_prioritized(ws, starts, goals, SETTINGS)
    space = build_coordination_space(traj)
    report = check_theory(traj, space)
    # brute force of Definition 4
    brute = set()
    for i in range(traj.n_robots):
        pts = traj.positions[i, : traj.lengths[i] + 1]
        for j in range(traj.n_robots):
            if i != j:
                for which, p in (("start", traj.starts[j]), ("goal", traj.goals[j])):
                    if np.any(np.linalg.norm(pts - p, axis=1) < 2 * traj.radius):
                        brute.add((i, j, which))
    assert {(c.robot, c.other, c.which) for c in conflicts(traj)} == brute
    assert report.non_conflicting == (not brute)


# ---------------------------------------------------------------- scenario files
BASE = {"family": "coordination", "robots": {"count": 5, "instance_seed": 2}, "policy": {"method": "tff"}}


def test_simulate_is_deterministic_and_safe():
    spec = load_scenario(BASE)
    a, b = simulate(spec, seed=7), simulate(spec, seed=7)
    assert np.array_equal(a.positions, b.positions)
    timings = {k: v for k, v in a.results.items() if k.endswith("_seconds")}  # wall times differ by nature
    assert a.results == {**b.results, **timings}
    summary = a.summary()
    assert summary["finished"] and not summary["deadlock"] and summary["collisions"] == 0
    assert summary["collision_events"] == 0


def test_learned_estimate_runs():
    spec = load_scenario({**BASE, "policy": {"method": "tfa", "estimate": "learned"}})
    trace = simulate(spec, seed=3)
    assert trace.results["finished"] and trace.results["collision_events"] == 0


@pytest.mark.parametrize("override, match", [
    ({"disturbance.base_probability": 1.0}, "disturbance.base_probability"),
    ({"disturbance.region_probability": -0.1}, "disturbance.region_probability"),
    ({"robots.radius": 0}, "robots.radius"),
    ({"policy.method": "fast"}, r"policy.method: expected 'rmtrack', 'tff', 'tfa', 'btpg' or 'optimal'"),
    ({"policy.estimate": "guess"}, "policy.estimate"),
    ({"robots.colour": "red"}, "robots.colour: expected no such key"),
])
def test_bad_scenarios(override, match):
    with pytest.raises(ScenarioError, match=match):
        load_scenario(BASE, overrides=override)


def test_explicit_start_inside_obstacle_names_the_field():
    data = {"family": "coordination", "robots": {"placement": "explicit", "starts": [[1500.0, 1550.0]], "goals": [[400.0, 200.0]]}}
    with pytest.raises(ScenarioError, match=r"robots.starts\[0\]: expected a point inside the free space"):
        load_scenario(data)


def test_trajectories_file_in_scenario(tmp_path):
    save_trajectories(fig2_example(), tmp_path / "plan.npz")
    (tmp_path / "s.yaml").write_text(
        "family: coordination\nworkspace: {preset: null, bounds: [[-20,-20],[20,-20],[20,20],[-20,20]]}\n"
        "robots: {placement: explicit, radius: 1.0, starts: [[-10,0],[-1,-6],[3,-3]], goals: [[10,0],[-1,10],[-5,9]]}\n"
        "trajectories: plan.npz\npolicy: {method: rmtrack}\n"
    )
    trace = simulate(load_scenario(tmp_path / "s.yaml"), seed=1)
    assert trace.results["finished"] and trace.positions.shape[1] == 3


# ---------------------------------------------------------------- CLI
def test_cli_check(tmp_path):
    save_trajectories(fig2_example(), tmp_path / "plan.csv")
    (tmp_path / "s.yaml").write_text(
        "family: coordination\nworkspace: {preset: null, bounds: [[-20,-20],[20,-20],[20,20],[-20,20]]}\n"
        "robots: {placement: explicit, radius: 1.0, starts: [[-10,0],[-1,-6],[3,-3]], goals: [[10,0],[-1,10],[-5,9]]}\n"
        "trajectories: plan.csv\n"
    )
    result = CliRunner().invoke(app, ["check", str(tmp_path / "s.yaml")])
    assert result.exit_code == 0, result.output
    assert "non-conflicting (Definition 4): yes" in result.output
    assert "disjoint collision segments (Theorem 4): no" in result.output
    assert "robot 0: steps" in result.output


def test_loaded_trajectory_through_an_obstacle_is_refused(tmp_path):
    save_trajectories(fig2_example(), tmp_path / "plan.npz")
    (tmp_path / "s.yaml").write_text(
        "family: coordination\nworkspace: {preset: null, bounds: [[-20,-20],[20,-20],[20,20],[-20,20]],"
        " obstacles: [[[4,-1],[6,-1],[6,1],[4,1]]]}\n"
        "robots: {placement: explicit, radius: 1.0, starts: [[-10,0],[-1,-6],[3,-3]], goals: [[10,0],[-1,10],[-5,9]]}\n"
        "trajectories: plan.npz\n"
    )
    with pytest.raises(ScenarioError, match=r"plan.npz: trajectories\[0\]\[\d+\]: expected a point inside the free space"):
        simulate(load_scenario(tmp_path / "s.yaml"), seed=1)
