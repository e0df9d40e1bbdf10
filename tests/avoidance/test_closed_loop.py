"""Closed-loop properties of the single-integrator B-UAVC."""

import numpy as np
import pytest

import robofleet
from robofleet.avoidance import CellGeometry, ObstacleSet, build_cells, cell_from_view, wall_planes
from robofleet.avoidance.navigation import NavigationParams, TeamNavigation
from robofleet.avoidance.navigation.progress import DeadlockParams


def swap(n, seed_boxes=False, **extra):
    m = {
        "family": "avoidance", "method": "bvc", "max_steps": 400,
        "robots": {"n": n, "sigma": 0.0, "layout": {"kind": "antipodal"}},
        "workspace": {"bounds": [-5, -5, 5, 5]},
    }
    if seed_boxes:
        m["workspace"]["obstacles"] = [{"center": [-4, 1], "size": [1, 1]}, {"center": [3, 4], "size": [1, 1]}, {"center": [0, -2], "size": [1, 1]}]
    m.update(extra)
    return robofleet.load_scenario(m)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("boxes", [False, True])
def test_bvc_without_noise_never_collides(seed, boxes):
    trace = robofleet.simulate(swap(6 + seed, boxes), seed=seed)
    s = trace.summary()
    assert s["collisions"] == 0 and s["obstacle_collisions"] == 0
    assert s["min_pair_distance"] >= 0.4 - 1e-7


def test_same_seed_same_trace_and_different_seed_differs():
    spec = robofleet.load_scenario("scenarios/avoidance/three_boxes.yaml", overrides={"max_steps": 60})
    t1, t2, t3 = (robofleet.simulate(spec, seed=s) for s in (7, 7, 8))
    for key in ("positions", "estimates", "controls"):
        np.testing.assert_array_equal(t1.arrays[key], t2.arrays[key])
    assert not np.array_equal(t1.positions, t3.positions)


def test_batch_cells_equal_each_robots_own_local_view():
    rng = np.random.default_rng(4)
    n = 40
    est = rng.uniform(-4, 4, (n, 2))
    L = rng.normal(size=(n, 2, 2)) * 0.1
    covs = L @ L.transpose(0, 2, 1) + 1e-3 * np.eye(2)
    box = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    geo = CellGeometry(ObstacleSet.build([box], [0.01 * np.eye(2)], 0.05), *wall_planes(np.array([[-5, -5], [5, -5], [5, 5], [-5, 5.0]])))
    cells = build_cells(est, covs, np.full(n, 0.2), 1.6, geo, local_box=2.0)
    for i in range(n):
        others = np.delete(np.arange(n), i)
        A, b, _ = cell_from_view(est[i], covs[i], 0.2, est[others], covs[others], 1.6, geo, 2.0)
        Ab, bb = cells.robot(i)
        key = lambda A, b: np.round(np.column_stack([A, b]), 8)[np.lexsort(np.round(np.column_stack([A, b]), 8).T)]
        np.testing.assert_allclose(key(A, b), key(Ab, bb), atol=1e-7)


def test_commanded_step_stays_inside_the_cell():
    rng = np.random.default_rng(8)
    n = 60
    est = rng.uniform(-4, 4, (n, 2))
    covs = np.broadcast_to(0.01 * np.eye(2), (n, 2, 2))
    geo = CellGeometry(ObstacleSet.build([], [], 0.0), *wall_planes(np.array([[-5, -5], [5, -5], [5, 5], [-5, 5.0]])))
    cells = build_cells(est, covs, np.full(n, 0.2), 1.6, geo, local_box=2.0)
    goals = -est
    nav = TeamNavigation("single_integrator", NavigationParams(enabled=False), DeadlockParams(enabled=False), n, 0.4, 0.1, 0.1, 2.0)
    u = nav.command(est, goals, cells).u
    inside_now = cells.contains(est)
    assert np.all(cells.contains(est + 0.1 * u)[inside_now])
    assert np.all(np.linalg.norm(u, axis=1) <= 0.4 + 1e-12)


def head_on(deadlock_enabled, liveness=False):
    return robofleet.load_scenario({
        "method": "bvc", "max_steps": 400,
        "robots": {"n": 2, "sigma": 0.0, "layout": {"kind": "explicit", "starts": [[-2, 0], [2, 0]], "goals": [[2, 0], [-2, 0]]}},
        "deadlock": {"enabled": deadlock_enabled}, "navigation": {"enabled": liveness},
    })


def test_deadlock_heuristic_resolves_a_head_on_swap():
    """The paper's controller (liveness rules off): appendix C frees the symmetric swap."""
    stuck = robofleet.simulate(head_on(False), seed=0).summary()
    freed = robofleet.simulate(head_on(True), seed=0).summary()
    assert stuck["arrived"] == 0.0  # the symmetric swap deadlocks at the bisector
    assert freed["success"] and freed["deadlock_detections"] >= 1


def test_right_hand_rule_alone_resolves_a_head_on_swap():
    """With the liveness rules and no appendix-C heuristic, both robots veer right at the
    bisector and pass: no deadlock is ever detected."""
    out = robofleet.simulate(head_on(False, liveness=True), seed=0).summary()
    assert out["success"] and out["deadlock_detections"] == 0


def test_buavc_team_with_noise_reaches_goals_without_collision():
    trace = robofleet.simulate(robofleet.load_scenario("scenarios/avoidance/circle_swap.yaml"), seed=1)
    s = trace.summary()
    assert s["collisions"] == 0 and s["arrived"] == 1.0


def test_singular_covariances_are_valid_input():
    """A robot certain along one axis (Σ singular but PSD), and an obstacle likewise."""
    spec = robofleet.load_scenario({
        "workspace": {"obstacle_cov": [[0.01, 0], [0, 0]], "obstacles": [{"center": [0, -2], "size": [1, 1]}]},
        "robots": {"cov": [[0.01, 0], [0, 0]], "n": 4, "layout": {"kind": "antipodal"}}, "max_steps": 120,
    })
    s = robofleet.simulate(spec, seed=1).summary()
    assert s["collisions"] == 0 and s["obstacle_collisions"] == 0


def test_loop_seconds_time_the_steps_without_the_recorders_declarations(monkeypatch):
    """``loop_seconds`` is the step loop alone: the recorder declaring (and filling) its
    arrays before the first step is set-up. A fake clock jumps 1000 s while the arrays
    are declared, and the steps still take well under that."""
    import types

    from robofleet.avoidance import metrics, simulation
    from robofleet.core import recorder

    now = [0.0]

    def perf_counter():
        now[0] += 1e-6
        return now[0]

    clock = types.SimpleNamespace(perf_counter=perf_counter)
    monkeypatch.setattr(recorder, "time", clock)
    monkeypatch.setattr(metrics, "time", clock)
    monkeypatch.setattr(simulation, "time", clock, raising=False)
    declare = recorder.Recorder.step

    def slow_declare(self, *args, **kwargs):
        now[0] += 1000.0
        return declare(self, *args, **kwargs)

    monkeypatch.setattr(recorder.Recorder, "step", slow_declare)
    trace = robofleet.simulate(swap(4, max_steps=5), seed=0)
    assert 0.0 <= trace.metadata["loop_seconds"] < 1000.0
