"""Scenario integration of the robot models: bad input, zero-noise runs, determinism."""

from pathlib import Path

import numpy as np
import pytest

import robofleet
from robofleet.avoidance.cell import Cells, Kind
from robofleet.avoidance.metrics import box_distance
from robofleet.avoidance.cell_model import ground_section
from robofleet.core.errors import ScenarioError

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios" / "avoidance"
MODEL_SCENARIOS = ["diff_drive.yaml", "double_integrator.yaml", "heterogeneous.yaml", "quadrotors_3d.yaml"]


def base(**extra):
    spec = {"family": "avoidance", "max_steps": 200, "goal_tolerance": 0.2,
            "robots": {"n": 4, "radius": 0.2, "v_max": 0.6, "sigma": 0.0, "layout": {"kind": "circle", "radius": 3.0}}}
    spec.update(extra)
    return spec


@pytest.mark.parametrize("name", MODEL_SCENARIOS)
def test_shipped_model_scenarios_validate(name):
    spec = robofleet.load_scenario(SCENARIOS / name)
    kinds = {(t.model.kind, t.model.controller) for t in spec.team_specs()}
    assert kinds and kinds != {("single_integrator", "one_step")}


@pytest.mark.parametrize("mapping,field", [
    (base(model={"kind": "hovercraft"}), "model.kind"),
    (base(model={"kind": "double_integrator"}), "model.a_max"),
    (base(model={"kind": "unicycle", "controller": "one_step"}), "model.omega_max"),
    (base(model={"kind": "single_integrator", "controller": "mpc", "mpc": {"horizon": 0}}), "model.mpc.horizon"),
    (base(model={"kind": "single_integrator", "controller": "mpc", "mpc": {"horizon": -3}}), "model.mpc.horizon"),
    (base(workspace={"obstacles": [{"center": [0, 0, 1], "size": [1, 1, 2]}]}), "workspace.obstacles.0.center"),
    (base(method="orca", model={"kind": "unicycle", "omega_max": 1.0}), "method"),
    (base(teams=[{"model": {"kind": "quadrotor", "controller": "mpc"}, "n": 2}]), "teams.0.model.kind"),
    (base(space3d={"bounds": [-5, -5, 0, 5, 5, 3], "boxes": [{"center": [0, 0], "size": [1, 1, 1]}]},
          teams=[{"model": {"kind": "quadrotor", "controller": "mpc"}, "n": 2}]), "space3d.boxes.0.center"),
    (base(model={"kind": "quadrotor", "controller": "one_step"}), "model.controller"),
])
def test_bad_model_input_is_one_clear_line(mapping, field):
    with pytest.raises(ScenarioError) as info:
        robofleet.load_scenario(mapping)
    message = str(info.value)
    assert "\n" not in message
    assert f": {field}: expected" in message, message


def test_unknown_model_error_lists_the_valid_names():
    with pytest.raises(ScenarioError) as info:
        robofleet.load_scenario(base(model={"kind": "hovercraft"}))
    assert "double_integrator" in str(info.value) and "quadrotor" in str(info.value)


@pytest.mark.parametrize("model", [
    {"kind": "double_integrator", "a_max": 1.0},
    {"kind": "unicycle", "omega_max": 1.5707963},
])
def test_ground_models_swap_without_collisions_at_zero_noise(model):
    spec = robofleet.load_scenario(base(model=model, max_steps=500, deadlock={"recover_steps": 30}))
    summary = robofleet.simulate(spec, seed=0).summary()
    assert summary["collisions"] == 0
    assert summary["min_pair_distance"] >= 0.4 - 1e-7
    assert summary["success"]


def test_heterogeneous_team_runs_without_collisions_at_zero_noise():
    mapping = base(
        dt=0.05, max_steps=160, method="buavc",
        space3d={"bounds": [-3, -3, 0, 3, 3, 2], "boxes": [{"center": [0, 0, 1], "size": [0.6, 0.6, 2], "yaw": 0.5}]},
        teams=[
            {"model": {"kind": "unicycle", "omega_max": 1.5707963}, "n": 2, "v_max": 0.6, "layout": {"kind": "circle", "radius": 2.0}},
            {"model": {"kind": "double_integrator", "a_max": 1.0}, "n": 2, "v_max": 0.6, "layout": {"kind": "circle", "radius": 2.0, "phase": 1.5707963}},
            {"model": {"kind": "quadrotor", "controller": "mpc", "mpc": {"horizon": 10}}, "n": 2, "v_max": 1.0,
             "layout": {"kind": "circle", "radius": 2.0, "height": 0.45, "phase": 0.785}},
        ],
    )
    trace = robofleet.simulate(robofleet.load_scenario(mapping), seed=0)
    summary = trace.summary()
    pos = trace.positions
    assert pos.shape[2] == 3
    ground = np.array([m != "quadrotor" for m in trace.metadata["models"]])
    np.testing.assert_allclose(pos[:, ground, 2], 0.2)  # ground robots stay in their plane
    assert summary["collisions"] == 0 and summary["obstacle_collisions"] == 0
    assert summary["min_pair_distance"] >= 0.4 - 1e-7
    # the quadrotors flew low enough to have to avoid the ground robots' spheres
    assert pos[:, ~ground, 2].min() < 0.6
    # everybody made progress toward the goal
    goals = np.asarray(trace.metadata["goals"])
    assert np.all(np.linalg.norm(pos[-1] - goals, axis=1) < np.linalg.norm(pos[0] - goals, axis=1) - 1.0)
    # the solver status of every robot-step: -1 without MPC, else 0 solved / 1 fallback / 2 arrived
    status = trace.arrays["mpc_status"]
    assert status.shape == (len(pos) - 1, len(ground)) and status.dtype == np.int8
    assert np.all(status[:, ground] == -1) and np.all(np.isin(status[:, ~ground], [0, 1, 2]))
    solved_for = np.isin(status, [0, 1]).sum()
    assert summary["mpc_fallback_steps"] == (status == 1).sum()
    assert summary["mpc_fallback_share"] == pytest.approx((status == 1).sum() / solved_for)


def test_orca_method_runs_and_is_deterministic():
    spec = robofleet.load_scenario(base(method="orca", robots={"n": 6, "radius": 0.2, "v_max": 0.6, "sigma": 0.05,
                                                                "layout": {"kind": "circle", "radius": 3.0}}))
    a = robofleet.simulate(spec, seed=4)
    b = robofleet.simulate(spec, seed=4)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert np.linalg.norm(a.positions[-1] - a.positions[0], axis=1).min() > 1.0


def test_robots_block_is_the_same_team_as_its_teams_spelling():
    """The short ``robots:`` + ``model:`` form is one team: the same trace as ``teams:``."""
    robots = {"n": 4, "radius": 0.2, "v_max": 0.4, "sigma": 0.1, "layout": {"kind": "circle", "radius": 3.0}}
    short = robofleet.load_scenario(base(robots=robots))
    team = {"name": "robots", "n": 4, "v_max": 0.4, "sigma": 0.1, "layout": {"kind": "circle", "radius": 3.0}}
    long = robofleet.load_scenario(base(robots={"radius": 0.2}, teams=[team]))
    assert short.team_specs() == long.team_specs()
    a, b = robofleet.simulate(short, seed=1), robofleet.simulate(long, seed=1)
    assert sorted(a.arrays) == sorted(b.arrays) and "headings" not in a.arrays  # no model with a heading
    for key in a.arrays:
        if key != "step_seconds":
            np.testing.assert_array_equal(a.arrays[key], b.arrays[key])
    assert a.events == b.events


def test_box_distance_matches_brute_force():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-3, 3, (50, 3))
    centre, size, yaw = np.array([[0.5, -0.2, 1.0]]), np.array([[1.0, 2.0, 0.5]]), np.array([0.7])
    z = rng.uniform(-0.5, 0.5, (200_000, 3)) * size[0]
    c, s = np.cos(yaw[0]), np.sin(yaw[0])
    box_pts = z @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) + centre[0]
    brute = np.min(np.linalg.norm(pts[:, None] - box_pts[None], axis=-1), axis=1)
    d = box_distance(pts, centre, size, yaw)[:, 0]
    assert np.all(d <= brute + 1e-9) and np.all(brute - d < 0.08)


def test_orca_robots_arrive_without_noise():
    spec = robofleet.load_scenario(base(method="orca", max_steps=400, orca={"time_horizon": 5.0}))
    summary = robofleet.simulate(spec, seed=2).summary()
    assert summary["arrived"] == 1.0 and summary["collisions"] == 0


def test_ground_section_ignores_floor_and_ceiling_but_not_robots():
    A = np.array([[[0, 0, -1.0], [0, 0, 1.0], [0.6, 0, 0.8], [0, 0, 1.0]]])
    b = np.array([[-0.32, 2.0, 1.0, 0.1]])
    kind = np.array([[Kind.WALL, Kind.WALL, Kind.ROBOT, Kind.ROBOT]], np.int8)
    cells = ground_section(Cells(A, b, np.ones((1, 4), bool), kind, np.zeros((1, 4), np.intp)), 0.2)
    assert list(cells.valid[0]) == [False, False, True, True]
    np.testing.assert_allclose(cells.A[0, 2], [1.0, 0.0])
    np.testing.assert_allclose(cells.b[0, 2], (1.0 - 0.8 * 0.2) / 0.6)
    assert cells.b[0, 3] < 0  # a quadrotor plane below the ground robot: its section is empty


def test_ground_robot_below_a_flying_one_keeps_its_half_of_the_space():
    """A ground robot (Σ = σ² diag(1, 1, 0)) and a quadrotor high above it: the pair's plane
    is the perpendicular bisector (both σ equal), not the horizontal plane through the
    ground robot that its singular Σ gives appendix B's separator; the buffers use the true
    Σ_i (the ground robot's has no z term), and the two rows are one plane."""
    from robofleet.avoidance.cell_model import cell_model, method_setup

    sigma = 0.05
    mapping = base(method="buavc", space3d={"bounds": [-3, -3, 0, 3, 3, 2.5]}, teams=[
        {"model": {"kind": "unicycle", "omega_max": 1.5707963}, "n": 1, "v_max": 0.6, "sigma": sigma,
         "layout": {"kind": "circle", "radius": 2.0}},
        {"model": {"kind": "quadrotor", "controller": "mpc"}, "n": 1, "v_max": 1.0, "sigma": sigma,
         "layout": {"kind": "circle", "radius": 2.0, "height": 1.5}}])
    spec = robofleet.load_scenario(mapping)
    setup = method_setup("buavc", spec.delta, 0.0)
    ground, air = np.array([0.0, 0.0, 0.2]), np.array([0.1, 0.0, 1.5])
    cells = cell_model(spec, setup).cells(np.stack([ground, air]), np.zeros((0, 3)))
    rows = [int(np.flatnonzero(cells.valid[i] & (cells.kind[i] == Kind.ROBOT))[0]) for i in range(2)]
    a_g, b_g = cells.A[0, rows[0]], cells.b[0, rows[0]]
    a_a, b_a = cells.A[1, rows[1]], cells.b[1, rows[1]]
    unit = (air - ground) / np.linalg.norm(air - ground)
    np.testing.assert_allclose(a_g, unit, atol=1e-9)
    np.testing.assert_allclose(a_a, -unit, atol=1e-9)
    q, r = setup.quantile, spec.robots.radius
    plane = unit @ (ground + air) / 2
    np.testing.assert_allclose(b_g, plane - r - q * sigma * np.linalg.norm(unit[:2]), atol=1e-9)
    np.testing.assert_allclose(b_a, -plane - r - q * sigma, atol=1e-9)
    section = ground_section(Cells(cells.A[:1], cells.b[:1], cells.valid[:1], cells.kind[:1], cells.source[:1]), 0.2)
    assert section.contains(ground[None, :2])[0]
    assert Cells(cells.A[1:], cells.b[1:], cells.valid[1:], cells.kind[1:], cells.source[1:]).contains(air[None])[0]


def test_ground_teams_in_3d_steer_by_the_roadmap_around_box_footprints():
    """The route of a ground team in 3-D is built on the footprints of the
    boxes that reach its plane (a box hanging above it is not an obstacle to it); flying
    teams get none."""
    from robofleet.avoidance.cell_model import ground_footprints
    from robofleet.avoidance.world import World
    from robofleet.core.geometry import box_vertices

    spec = robofleet.load_scenario(SCENARIOS / "heterogeneous.yaml")
    space = spec.space3d.model_copy(update={"boxes": [*spec.space3d.boxes, type(spec.space3d.boxes[0])(center=[2, 2, 2.0], size=[1, 1, 0.5])]})
    footprints = ground_footprints(space, spec.ground_height(), spec.robots.radius)
    box = spec.space3d.boxes[0]
    assert len(footprints) == 1
    np.testing.assert_allclose(footprints[0], box_vertices(box.center, box.size, box.yaw))
    world = World(spec, np.random.default_rng(0))
    ground, air = world.groups
    assert ground.nav.route is not None and air.nav.route is None


@pytest.mark.parametrize("name", ["heterogeneous.yaml", "quadrotors_3d.yaml"])
def test_shipped_3d_step_budgets_follow_the_straight_line_rule(name):
    from robofleet.avoidance.spec import straight_line_budget

    spec = robofleet.load_scenario(SCENARIOS / name)
    assert spec.max_steps == straight_line_budget(spec)
    assert "straight_line_budget" in (SCENARIOS / name).read_text()


@pytest.mark.parametrize("name", ["heterogeneous.yaml", "quadrotors_3d.yaml", "circle_swap.yaml"])
def test_metadata_per_robot_lists_are_the_teams_values_as_plain_json(name):
    """The run's metadata repeats each team's value per robot, every element a plain
    Python value, and equals the element-by-element conversion of the same fields."""
    import json

    from robofleet.avoidance.world import World, team_covariance
    from robofleet.core.trace import to_plain

    spec = robofleet.load_scenario(SCENARIOS / name)
    world = World(spec, np.random.default_rng(0))
    meta = world.metadata()
    teams = spec.team_specs()
    per_robot = lambda values: [v for t, v in zip(teams, values) for _ in range(t.n)]  # noqa: E731
    covs = [team_covariance(t, world.dim) for t in teams]
    shared = world.dim == 2 and covs[0].ndim == 2 and all(np.array_equal(c, covs[0]) for c in covs)
    expected = to_plain({
        "method": spec.method, "dt": spec.dt, "radius": spec.robots.radius, "goals": world.goals, "starts": world.starts,
        "goal_tolerance": spec.goal_tolerance, "delta": spec.delta, "local_box": spec.local_box, "dim": world.dim,
        "teams": per_robot([t.name for t in teams]), "models": per_robot([t.model.kind for t in teams]),
        "controllers": per_robot([t.model.controller for t in teams]), "v_max": per_robot([t.v_max for t in teams]),
        "sigma": per_robot([t.largest_sigma() for t in teams]), "robot_cov": covs[0] if shared else None,
        "boxes": [{"center": list(b.center), "size": list(b.size), "yaw": b.yaw} for b in spec.space3d.boxes] if spec.space3d else [],
        "bounds3d": list(spec.space3d.bounds) if spec.space3d is not None else None,
    })
    assert meta == expected and list(meta) == list(expected)
    assert json.dumps(meta) == json.dumps(expected)
    for key in ("teams", "models", "controllers", "v_max", "sigma"):
        assert len(meta[key]) == world.n and all(type(v) in (str, float, int) for v in meta[key])
