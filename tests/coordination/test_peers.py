"""The peers of label flipping (BTPG, the optimal orders) and the shared metric: each
method's guarantee as a test, on random instances the code has not seen (seeded).

* BTPG: every labeling of the switchable obstacles leaves the whole segment graph acyclic
  (brute force over the labelings); executions under random and adversarial delays never
  collide, never hold a cycle in the active segment graph, never deadlock
  (non-conflicting plans: Theorems 1, 2).
* optimal: the schedule kernels equal a plain reference schedule; the search's choice is
  never worse than the orders it started from, and when the budget suffices it is the
  optimum over every labeling of the open obstacles (brute force); executions never
  collide, never hold a cycle, never deadlock.
* The delay-only lower bound equals a plain per-robot loop over the run's own draws.
"""

from __future__ import annotations

import itertools
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coordination_instances import random_instance, roundabout_instance
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.btpg import classify_switchable, plan_sides, statically_switchable
from robofleet.coordination.label_flipping import KnownProbabilities
from robofleet.coordination.metrics import delay_only_arrival_steps, waiting_removed_share
from robofleet.coordination.optimal import (
    OptimalOrders, OptimalSettings, OrderGraph, ScheduleModel, expected_step_times, open_obstacles, solve_orders,
)
from robofleet.coordination.plan_execution import DisturbanceStream, Method, PlanExecutor, Variant
from robofleet.coordination.segment_graph import build_segment_layout, has_cycle_full

SEEDS = st.integers(0, 2**32 - 1)


def instance(seed: int, n_robots: int, kind: str):
    """A random non-conflicting plan: crossing lines, a crowded ring, or a roundabout."""
    rng = np.random.default_rng(seed)
    if kind == "roundabout":
        traj, space = roundabout_instance(rng, n_robots)
        return traj, space, build_segment_layout(space)
    return random_instance(rng, n_robots, ring=kind == "ring")


def run_method(traj, space, layout, method: Method, seed: int, p: float | np.ndarray = 0.3, disturbed=None, **kw):
    prob = np.broadcast_to(np.asarray(p, dtype=float), traj.positions.shape[:2]).copy()
    executor = PlanExecutor(traj, space, Variant(method, True), KnownProbabilities(prob, traj.dt), prob, layout=layout,
                            disturbed=disturbed, record_cycles=True, **kw)
    return executor, executor.run(seed, 20000)


def stalls(seed: int, n_robots: int):
    """Adversarial delays: each robot is held still during random windows of up to 200 steps."""
    rng = np.random.default_rng(seed)
    windows = [(rng.integers(0, 300, 3), rng.integers(1, 200, 3)) for _ in range(n_robots)]

    def disturbed(t, x):
        return np.array([bool(np.any((t >= s) & (t < s + d))) for s, d in windows])
    return disturbed


# ---------------------------------------------------------------- BTPG
@settings(max_examples=60, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(3, 7), kind=st.sampled_from(["lines", "ring", "roundabout"]))
def test_btpg_every_labeling_of_the_switchable_obstacles_is_acyclic(seed, n_robots, kind):
    traj, space, layout = instance(seed, n_robots, kind)
    switchable = classify_switchable(space, layout).switchable
    assert not np.any(switchable & ~statically_switchable(space))
    ids = np.flatnonzero(switchable)
    nothing_entered = np.full(space.n_robots, -1)
    rng = np.random.default_rng(seed)
    labelings = (itertools.product((0, 1), repeat=len(ids)) if len(ids) <= 9
                 else (rng.integers(0, 2, len(ids)) for _ in range(512)))
    for bits in labelings:
        labels = space.initial_labels.copy()
        labels[ids] = np.where(np.asarray(bits, dtype=bool), space.robot_i[ids], space.robot_j[ids])
        assert not has_cycle_full(layout, labels, nothing_entered)


def test_btpg_classification_is_not_vacuous():
    """Across instances, some obstacles are switchable and some are kept fixed for a cycle."""
    switchable, fixed = 0, 0
    for seed in range(12):
        traj, space, layout = instance(seed, 6, "ring")
        c = classify_switchable(space, layout)
        switchable += c.n_switchable
        fixed += int(statically_switchable(space).sum()) - c.n_switchable
    assert switchable > 0 and fixed > 0


def test_btpg_budget_keeps_later_candidates_fixed():
    traj, space, layout = instance(3, 6, "ring")
    full, none = classify_switchable(space, layout), classify_switchable(space, layout, budget=0)
    assert none.n_switchable == 0 and none.tested == 0 and full.tested == full.candidates


@settings(max_examples=60, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(3, 7), kind=st.sampled_from(["lines", "ring", "roundabout"]),
       p=st.sampled_from([0.0, 0.3, 0.8]), adversarial=st.booleans())
def test_btpg_never_collides_holds_a_cycle_or_deadlocks(seed, n_robots, kind, p, adversarial):
    traj, space, layout = instance(seed, n_robots, kind)
    _, run = run_method(traj, space, layout, Method.BTPG, seed, p, stalls(seed, n_robots) if adversarial else None)
    assert run.collisions == 0 and not run.deadlock and run.finished
    assert not any(run.cycle_log)


def test_btpg_flips_only_switchable_obstacles_once_each():
    flipped = 0
    for seed in range(10):
        traj, space, layout = instance(seed, 6, "ring")
        executor, run = run_method(traj, space, layout, Method.BTPG, seed, 0.5)
        obstacles = [e["obstacle"] for e in run.events if e["kind"] == "flip"]
        assert executor.btpg_classification.switchable[obstacles].all()
        assert len(obstacles) == len(set(obstacles))
        flipped += len(obstacles)
    assert flipped > 0


# ---------------------------------------------------------------- optimal: the model
def reference_cost(model: ScheduleModel, labels: np.ndarray, deferred: np.ndarray) -> float:
    """The expected-duration schedule's cost recomputed from scratch, without the kernels:
    every vertex not entered, every active edge, earliest times by repeated relaxation;
    ``inf`` when the graph has a cycle."""
    g, layout_side = model.graph, plan_sides(model.space, labels)
    sides = np.zeros(2 * model.space.n_obstacles, dtype=bool)
    sides[layout_side[~deferred]] = True
    x, cum, step, now = model.x, model.cumulative, model.step, model.now
    live = np.flatnonzero(x[g.node_robot] < g.node_start)
    edges = []
    for v in live:
        r, prev = g.node_robot[v], v - 1
        if prev >= 0 and g.node_robot[prev] == r and x[r] < g.node_start[prev]:
            edges.append((prev, v, cum[r, g.node_start[v]] - cum[r, g.node_start[prev]]))
    for e in range(len(g.edge_src)):
        side = np.searchsorted(g.side_ptr, e, side="right") - 1
        u, v = g.edge_src[e], g.edge_dst[e]
        if sides[side] and x[g.node_robot[u]] < g.node_start[u] and x[g.node_robot[v]] < g.node_start[v]:
            edges.append((u, v, step[g.node_robot[v], g.node_start[v] - 1]))
    times = {v: now + cum[g.node_robot[v], g.node_start[v]] - cum[g.node_robot[v], x[g.node_robot[v]]] for v in live}
    successors = {v: [] for v in live}
    indegree = dict.fromkeys(live, 0)
    for u, v, w in edges:
        successors[u].append((v, w))
        indegree[v] += 1
    ready = [v for v in live if indegree[v] == 0]
    seen = 0
    while ready:  # Kahn's order: each vertex final when taken
        u = ready.pop()
        seen += 1
        for v, w in successors[u]:
            times[v] = max(times[v], times[u] + w)
            indegree[v] -= 1
            if indegree[v] == 0:
                ready.append(v)
    if seen < len(live):
        return float("inf")
    total = 0.0
    for r in range(len(x)):
        k = g.lengths[r]
        if x[r] >= k:
            total += model.arrived[r]
            continue
        mine = [v for v in live if g.node_robot[v] == r and g.node_start[v] <= k]
        last = max(mine, key=lambda v: g.node_start[v]) if mine else None
        total += (times[last] + cum[r, k] - cum[r, g.node_start[last]]) if last is not None else now + cum[r, k] - cum[r, x[r]]
    return total


def decision_model(seed: int, n_robots: int, kind: str, max_open: int = 6):
    """A random state of a random plan (RMTRACK run under random disturbances up to a random
    step) and the model of a decision there."""
    traj, space, layout = instance(seed, n_robots, kind)
    rng = np.random.default_rng(seed)
    prob = rng.choice([0.05, 0.3, 0.85], size=traj.positions.shape[:2])
    executor = PlanExecutor(traj, space, Variant(Method.RMTRACK, False), KnownProbabilities(prob, traj.dt), prob)
    state = executor.start(seed)
    decision, t = executor.decide(state, 0), 0
    stop = int(rng.integers(0, int(traj.lengths.max())))
    while not decision.stop and t < stop:
        executor.move(state, decision, t)
        t += 1
        decision = executor.decide(state, t)
    graph = OrderGraph.of(layout, space)
    closed = ~statically_switchable(space)
    open_ids, deferred = open_obstacles(space, state.labels, state.x, closed, horizon=int(rng.integers(5, 80)), max_open=max_open)
    step, cumulative = expected_step_times(prob, traj.dt)
    arrived = np.where(state.arrival >= 0, state.arrival, 0) * traj.dt
    model = ScheduleModel(graph, space, state.labels, state.x, t * traj.dt, step, cumulative, arrived, open_ids, deferred)
    return model, state.labels, deferred


def labels_for(model: ScheduleModel, labels: np.ndarray, choice) -> np.ndarray:
    new = labels.copy()
    o = model.open
    new[o] = np.where(np.asarray(choice) == 1, model.space.robot_i[o], model.space.robot_j[o])
    return new


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(3, 7), kind=st.sampled_from(["lines", "ring", "roundabout"]))
def test_optimal_schedule_equals_the_reference(seed, n_robots, kind):
    model, labels, deferred = decision_model(seed, n_robots, kind)
    rng = np.random.default_rng(seed)
    for _ in range(4):
        choice = rng.integers(0, 2, len(model.open)).astype(np.int8)
        scheduled = model.schedule(choice)
        expected = reference_cost(model, labels_for(model, labels, choice), deferred)
        if scheduled is None:
            assert expected == float("inf")
        else:
            assert model.cost(scheduled[0]) == pytest.approx(expected, rel=1e-9, abs=1e-9)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(3, 7), kind=st.sampled_from(["lines", "ring", "roundabout"]),
       budget=st.sampled_from([0, 1, 3, 1000]))
def test_optimal_never_worse_than_its_start_and_exact_within_budget(seed, n_robots, kind, budget):
    model, labels, deferred = decision_model(seed, n_robots, kind)
    choice, cost, start_cost, bound, expansions, exhausted = solve_orders(model, budget)
    assert start_cost == pytest.approx(reference_cost(model, labels, deferred), rel=1e-9, abs=1e-9)
    assert cost <= start_cost + 1e-9  # never worse than the orders it started from
    assert cost == pytest.approx(reference_cost(model, labels_for(model, labels, choice), deferred), rel=1e-9, abs=1e-9)
    assert bound <= cost + 1e-9 and expansions <= budget
    if not exhausted:  # exact: the optimum over every labeling of the open obstacles
        best = min(reference_cost(model, labels_for(model, labels, bits), deferred)
                   for bits in itertools.product((0, 1), repeat=len(model.open)))
        assert cost == pytest.approx(best, rel=1e-9, abs=1e-9)


def test_optimal_search_is_exercised():
    """Across random decisions the search both branches and improves on the current orders."""
    improved = branched = 0
    for seed in range(30):
        model, _, _ = decision_model(seed, 6, "ring")
        _, cost, start_cost, _, expansions, _ = solve_orders(model, 1000)
        improved += cost < start_cost - 1e-9
        branched += expansions > 0
    assert improved > 0 and branched > 0


# ---------------------------------------------------------------- optimal: executions
class RecordingOrders(OptimalOrders):
    """Checks every decision: never worse than its start, labels changed only on open obstacles."""

    def decide(self, labels, progress, closed, t, probability, arrival_steps):
        solution = super().decide(labels, progress, closed, t, probability, arrival_steps)
        if solution is not None:
            assert solution.cost <= solution.start_cost + 1e-9
            changed = np.flatnonzero(solution.labels != labels)
            assert np.isin(changed, solution.open).all()
        return solution


@settings(max_examples=60, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(3, 7), kind=st.sampled_from(["lines", "ring", "roundabout"]),
       p=st.sampled_from([0.0, 0.3, 0.8]), adversarial=st.booleans(), budget=st.sampled_from([0, 2, 32]))
def test_optimal_never_collides_holds_a_cycle_or_deadlocks(seed, n_robots, kind, p, adversarial, budget):
    traj, space, layout = instance(seed, n_robots, kind)
    settings_ = OptimalSettings(horizon=int(seed % 60) + 5, max_open=int(seed % 7) + 1, node_budget=budget, period=int(seed % 9) + 1)
    with mock.patch("robofleet.coordination.plan_execution.OptimalOrders", RecordingOrders):
        _, run = run_method(traj, space, layout, Method.OPTIMAL, seed, p, stalls(seed, n_robots) if adversarial else None,
                            optimal=settings_)
    assert run.collisions == 0 and not run.deadlock and run.finished
    assert not any(run.cycle_log)


def test_optimal_decides_and_flips():
    flips = decisions = 0
    for seed in range(8):
        traj, space, layout = instance(seed, 6, "ring")
        _, run = run_method(traj, space, layout, Method.OPTIMAL, seed, 0.5)
        flips += run.flips
        decisions += run.stats["decisions"]
    assert flips > 0 and decisions > 0


# ---------------------------------------------------------------- the shared metric
@pytest.mark.parametrize("seed", range(5))
def test_delay_only_arrivals_equal_a_plain_loop(seed):
    rng = np.random.default_rng(seed)
    lengths = rng.integers(0, 400, 6)
    probability = rng.choice([0.0, 0.05, 0.85], size=(6, int(lengths.max()) + 1))
    stream = DisturbanceStream(seed, 6)
    got = delay_only_arrival_steps(stream, probability, lengths, 5000)
    for i in range(6):
        x, t = 0, 0
        while x < lengths[i]:
            x += stream.uniforms(t)[i] >= probability[i, x]
            t += 1
        assert got[i] == t


def test_delay_only_bound_cut_by_the_step_budget():
    stream = DisturbanceStream(0, 2)
    got = delay_only_arrival_steps(stream, np.full((2, 101), 0.5), np.array([0, 100]), 50)
    assert got.tolist() == [0, -1]


def test_a_robot_alone_has_no_unnecessary_waiting():
    traj, space, layout = instance(0, 3, "lines")
    one = traj.__class__(traj.positions[:1], traj.lengths[:1], traj.radius, traj.dt)
    prob = np.full(one.positions.shape[:2], 0.4)
    run = PlanExecutor(one, build_coordination_space(one), Variant(Method.RMTRACK, False), KnownProbabilities(prob, one.dt), prob).run(7, 20000)
    assert run.arrival_steps.tolist() == delay_only_arrival_steps(DisturbanceStream(7, 1), prob, one.lengths, 20000).tolist()


def test_waiting_removed_share():
    assert waiting_removed_share(0.0, 10.0) == 1.0
    assert waiting_removed_share(10.0, 10.0) == 0.0
    assert waiting_removed_share(15.0, 10.0) == -0.5
    assert np.isnan(waiting_removed_share(1.0, 0.0)) and np.isnan(waiting_removed_share(float("nan"), 3.0))


# ---------------------------------------------------------------- scenarios, verdicts, the reproduction's table
def test_stations_need_the_warehouse_and_enough_stations():
    from robofleet.core.errors import ScenarioError
    from robofleet.scenarios import load_scenario
    with pytest.raises(ScenarioError, match="robots.placement: expected stations only with workspace preset warehouse"):
        load_scenario("coordination/x_corridor_20", {"robots.placement": "stations"})
    with pytest.raises(ScenarioError, match="robots.count: expected at most 224 robots with placement: stations"):
        load_scenario("coordination/warehouse_50", {"robots.count": 225})


def test_warehouse_instances_follow_the_seed_and_keep_robots_at_distinct_stations():
    from robofleet.coordination.maps import sample_station_instance, warehouse_stations, warehouse_workspace
    a, b = sample_station_instance(120, np.random.default_rng(1)), sample_station_instance(120, np.random.default_rng(1))
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    points = np.concatenate(a)
    assert len(np.unique(points, axis=0)) == 240
    assert np.isin(points.view([("x", float), ("y", float)]), warehouse_stations().view([("x", float), ("y", float)])).all()
    assert warehouse_workspace().clearance(points).min() >= 15.0  # a robot of radius 15 fits at every station


@pytest.mark.parametrize("method", ["btpg", "optimal"])
def test_check_states_the_guarantee_of_the_peers(method):
    from robofleet.coordination import check
    from robofleet.scenarios import load_scenario
    verdict = {g.name: g for g in check(load_scenario("coordination/fig2_three_robots", {"policy.method": method}))}
    deadlock = verdict["no deadlock under this policy"]
    assert deadlock.holds and deadlock.reference == "Theorems 1, 2" and f"method {method}" in deadlock.consequence


def test_peers_table_pairs_the_methods_and_measures_against_rmtrack():
    import pandas as pd
    from robofleet.experiments.reproductions.coordination_peers import peers_summary
    rows = []
    for seed, waits in ((1, {"RMTRACK (checked)": 10.0, "RMTRACK+TFF (checked)": 4.0, "RMTRACK+TFA (checked)": 5.0, "BTPG": 8.0, "optimal": 2.0}),
                        (2, {"RMTRACK (checked)": 30.0, "RMTRACK+TFF (checked)": 12.0, "RMTRACK+TFA (checked)": 9.0, "BTPG": 30.0, "optimal": 6.0})):
        for variant, wait in waits.items():
            rows.append({"n_robots": 5, "seed": seed, "variant": variant, "success": True, "finished": True, "deadlock": False,
                         "collisions": 0, "plan_id": f"p{seed}", "unnecessary_waiting": wait, "mean_travel_time": 50.0 + wait / 5,
                         "flips": 1, "step_decision_seconds": 1e-5, "decision_seconds": 0.01, "decisions": 2, "budget_exhausted": 1,
                         "switchable": 3, "n_obstacles": 6, "error": None})
    table = peers_summary({"coordination_peers_fig6": pd.DataFrame(rows)}).set_index("method")
    assert list(table.index) == ["RMTRACK", "RMTRACK+TFF (checked)", "RMTRACK+TFA (checked)", "BTPG", "optimal"]
    assert table.loc["optimal", "waiting_removed"] == pytest.approx(1 - 8 / 40)
    assert table.loc["BTPG", "waiting_removed"] == pytest.approx(1 - 38 / 40)
    assert table.loc["RMTRACK", "waiting_removed"] == 0.0
    assert table["paired"].all() and table.loc["BTPG", "switchable"] == 0.5 and table.loc["optimal", "exhausted_share"] == 0.5
