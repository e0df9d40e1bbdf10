"""The compiled paths give exactly what the numpy/Python code gives: plain steps of the
execution, the planner's space-time A*, the segment graph's topological order and the
cached disturbance draws, each against a reference on random cases; the TFA roll-out's
compiled loop against the same loop interpreted."""

from __future__ import annotations

import heapq
import itertools
import types

import numpy as np
import pytest

from coordination_instances import line, random_instance
from robofleet import load_scenario, simulate
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.label_flipping import FlipContext, KnownProbabilities, _blocked, _rollout, _step_times, pair_rollout
from robofleet.coordination.maps import sample_flow_instance, x_corridor_workspace
from robofleet.coordination.plan_execution import DISTURBANCE_BLOCK, Method, PlanExecutor, Variant, disturbance_block
from robofleet.coordination.planner import PlannerSettings, SpaceTimeSearch, plan_prioritized, paths_to_array
from robofleet.coordination.segment_graph import IncrementalCycleDetector, build_segment_layout, earliest_first_order
from robofleet.coordination.trajectories import make_trajectories
from robofleet.core.rng import keyed_generator

TIMING = {"decision_seconds", "plan_seconds", "wall_seconds", "step_decision_seconds", "offline_seconds"}


# ---------------------------------------------------------------- plain steps
def execution_pair(traj, space, variant, p, flip_seed, max_steps, **kw):
    """The same run with the compiled plain steps and with every step through numpy."""
    prob = np.asarray(p, float) * np.ones(traj.positions.shape[:2])
    runs = []
    for compiled in (True, False):
        executor = PlanExecutor(traj, space, variant, KnownProbabilities(prob, traj.dt), prob, flip_test=random_flips(flip_seed),
                                compiled=compiled, **kw)
        runs.append(executor.run(seed=flip_seed, max_steps=max_steps))
    return runs


def random_flips(seed: int, probability: float = 0.8):
    """A flip test that says yes at random (the same answers for the same seed)."""
    rng = np.random.default_rng(seed)
    return lambda ctx: bool(rng.random() < probability)


def assert_same_execution(a, b):
    for name in ("progress", "waiting", "labels", "arrival_steps"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.events == b.events
    for name in ("deadlock", "finished", "collisions", "flips", "refused_flips", "flip_tests"):
        assert getattr(a, name) == getattr(b, name), name


def test_plain_steps_equal_numpy_steps_on_random_plans():
    seen = {"deadlock": 0, "flips": 0, "timeout": 0}
    for case in range(40):
        rng = np.random.default_rng(case)
        traj, space, _ = random_instance(rng, 6 if case % 4 else 3 + case % 5, ring=case % 4 != 3)
        method = Method.RMTRACK if case % 8 == 7 else (Method.TFF if case % 2 else Method.TFA)
        p = rng.choice([0.0, 0.3, 0.6], size=traj.positions.shape[:2]) if case % 5 == 1 else 0.3
        max_steps = int(rng.integers(20, 80)) if case % 10 == 4 else 5000
        compiled, reference = execution_pair(traj, space, Variant(method, case % 3 == 0), p, case, max_steps)
        assert_same_execution(compiled, reference)
        for key in ("deadlock", "flips"):
            seen[key] += getattr(compiled, key)
        seen["timeout"] += any(e["kind"] == "timeout" for e in compiled.events)
    assert all(seen.values()), seen  # the cases reached deadlocks, flips and step budgets


def test_plain_steps_equal_numpy_steps_when_robots_collide():
    """A plan that collides (robots 0 and 1 start and drive side by side closer than 2r; the
    coordination space is built without the plan check): the contacts are counted and
    reported at the same steps."""
    paths = [line((0, 0), (10, 0), 0.3), line((0.5, 0.5), (10.5, 0.5), 0.3), line((5, -5), (5, 5), 0.3)]
    traj = make_trajectories(paths, 0.5, 0.1)
    space = build_coordination_space(traj, check_plan=False)
    for method, check in itertools.product(Method, (False, True)):
        compiled, reference = execution_pair(traj, space, Variant(method, check), 0.2, 3, 500)
        assert compiled.collisions > 0
        assert_same_execution(compiled, reference)


def trace_fields(trace):
    arrays = {k: v for k, v in trace.arrays.items() if k != "step_seconds"}
    results = {k: v for k, v in trace.results.items() if k not in TIMING}
    return arrays, trace.events, results


@pytest.mark.parametrize("method, check, seed", [("rmtrack", False, 1), ("tff", True, 2), ("tfa", False, 3), ("tfa", True, 4)])
def test_simulate_with_plain_steps_records_the_numpy_trace(monkeypatch, method, check, seed):
    spec = load_scenario("coordination/x_corridor_20", {"robots.count": 10, "robots.instance_seed": None,
                                                       "policy.method": method, "policy.deadlock_check": check})
    compiled = simulate(spec, seed=seed)
    monkeypatch.setattr(PlanExecutor, "compiles", property(lambda self: False))
    reference = simulate(spec, seed=seed)
    (a, ev_a, res_a), (b, ev_b, res_b) = trace_fields(compiled), trace_fields(reference)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    assert ev_a == ev_b and res_a == res_b
    steps = compiled.arrays["step_seconds"]
    assert len(steps) == compiled.metadata["n_steps"] and np.all(steps >= 0)


def test_disturbance_blocks_are_the_keyed_streams():
    draws = disturbance_block(5, 3, 2)
    assert draws.shape == (DISTURBANCE_BLOCK, 3) and not draws.flags.writeable
    for robot in range(3):
        assert np.array_equal(draws[:, robot], keyed_generator(5, "disturbance", robot, 2).random(DISTURBANCE_BLOCK))


# ---------------------------------------------------------------- planner
def reference_astar(search: SpaceTimeSearch):
    """The space-time A* written with Python containers and numpy move checks."""
    nodes, s = search.roadmap.nodes, search.s

    def clear(a, b, t0, d):
        if search.higher.shape[1] == 0:
            return True
        pts = a + (b - a) * (np.arange(1, d + 1)[:, None] / d)
        t = np.minimum(np.arange(t0 + 1, t0 + d + 1), len(search.higher) - 1)
        return bool(np.all(((search.higher[t] - pts[:, None]) ** 2).sum(-1) >= search.reach2))

    if not clear(nodes[search.start], nodes[search.start], -1, 1):
        return None
    heap, parent, closed, expansions = [(float(search.h[search.start]), 0, search.start)], {(search.start, 0): None}, set(), 0
    while heap and expansions < s.max_expansions:
        _, t, u = heapq.heappop(heap)
        if (u, t) in closed:
            continue
        closed.add((u, t))
        expansions += 1
        if u == search.goal and t >= search.goal_free_from:
            chain, state = [], (u, t)
            while state is not None:
                chain.append(state)
                state = parent[state]
            return np.array(chain[::-1])
        ptr = slice(search.adj_ptr[u], search.adj_ptr[u + 1])
        for v, d in [(u, s.wait_steps)] + list(zip(search.adj_to[ptr].tolist(), search.adj_dur[ptr].tolist())):
            key = (v, t + d)
            if key in closed or key in parent or t + d > s.max_steps or not clear(nodes[u], nodes[v], t, d):
                continue
            parent[key] = (u, t)
            heapq.heappush(heap, (t + d + float(search.h[v]), t + d, v))
    return None


def test_compiled_astar_equals_the_reference_search():
    ws = x_corridor_workspace()
    settings = PlannerSettings(radius=15.0, speed=50.0, dt=0.1, wait_steps=5)
    for seed in range(3):
        starts, goals = sample_flow_instance(ws, 6, 15.0, np.random.default_rng(seed))
        traj = plan_prioritized(ws, starts, goals, settings)
        searches = recorded_searches(ws, starts, goals, settings, traj)
        for search in searches:
            chain = reference_astar(search)
            assert chain is not None
            assert np.array_equal(search._trajectory(chain), search.run())


def recorded_searches(ws, starts, goals, settings, traj):
    """The planner's searches of one instance, rebuilt from its plan (robot i against robots < i)."""
    from robofleet.coordination.planner import _clear_of, build_roadmap

    n = len(starts)
    roadmap = build_roadmap(ws, settings, np.concatenate([starts, goals]))
    base = len(roadmap.nodes) - 2 * n
    distances = roadmap.distances_to_edges(np.concatenate([starts, goals]))
    paths = [traj.positions[i, : traj.lengths[i] + 1] for i in range(n)]
    return [SpaceTimeSearch(roadmap, settings, base + i, base + n + i, np.asarray(paths_to_array(paths[:i])),
                            _clear_of(distances[i + 1:n], len(roadmap.edges), 2 * settings.radius)) for i in range(n)]


# ---------------------------------------------------------------- TFA roll-out
def interpreted_rollout(ctx: FlipContext, first: int):
    """:func:`pair_rollout` with its loop run by the Python interpreter (numba's ``py_func``)."""
    s, side = ctx.space, ctx.side
    x_w, x_a = int(ctx.progress[ctx.waiter]), int(ctx.progress[ctx.other])
    target_w, target_a = int(s.side_hi[side]) + 1, int(s.side_hi[side ^ 1]) + 1
    wait_w, wait_a = (side if first == ctx.other else -1), (side ^ 1 if first == ctx.waiter else -1)
    with_python_blocked = {**_rollout.py_func.__globals__, "_blocked": _blocked.py_func}
    loop = types.FunctionType(_rollout.py_func.__code__, with_python_blocked)
    return loop(_step_times(ctx, ctx.waiter, x_w, target_w), _step_times(ctx, ctx.other, x_a, target_a), x_w, x_a,
                target_w, target_a, wait_w, wait_a, s.side_lo, s.side_hi, s.side_offset, s.profile)


def test_compiled_rollout_equals_the_interpreted_loop():
    rng = np.random.default_rng(3)
    compared = 0
    for _ in range(8):
        traj, space, _ = random_instance(rng, 5, ring=True)
        prob = rng.uniform(0.0, 0.9, traj.positions.shape[:2])
        times = KnownProbabilities(prob, traj.dt)
        for side in range(2 * space.n_obstacles):
            w, a = int(space.side_waiter[side]), int(space.side_other[side])
            for _ in range(3):
                x = np.zeros(traj.n_robots, dtype=np.intp)
                x[w] = rng.integers(0, max(1, space.side_lo[side]))
                x[a] = rng.integers(0, space.side_other_hi[side] + 2)
                ctx = FlipContext(space, side, w, a, x, times)
                for first in (w, a):
                    assert pair_rollout(ctx, first) == interpreted_rollout(ctx, first)
                    compared += 1
    assert compared > 100


# ---------------------------------------------------------------- topological order
def reference_order(n_nodes, src, dst, start, entered):
    succ = [{} for _ in range(n_nodes)]
    indegree = np.zeros(n_nodes, dtype=int)
    for u, w in zip(src, dst):
        succ[u][w] = succ[u].get(w, 0) + 1
        indegree[w] += not entered[u]
    order = np.full(n_nodes, -1)
    done = np.flatnonzero(entered)
    order[done] = np.arange(len(done))
    position = len(done)
    ready = [(int(start[x]), x) for x in range(n_nodes) if not entered[x] and indegree[x] == 0]
    heapq.heapify(ready)
    while ready:
        _, x = heapq.heappop(ready)
        order[x], position = position, position + 1
        for y, count in succ[x].items():
            indegree[y] -= count
            if indegree[y] == 0 and not entered[y]:
                heapq.heappush(ready, (int(start[y]), y))
    return order if position == n_nodes else np.full(n_nodes, -1)


def test_earliest_first_order_equals_the_reference():
    rng = np.random.default_rng(8)
    cyclic = 0
    for case in range(200):
        v = int(rng.integers(1, 30))
        rank = rng.permutation(v)
        e = int(rng.integers(0, 3 * v))
        src, dst = rng.integers(0, v, e), rng.integers(0, v, e)
        if case % 2:  # a DAG with parallel edges: edges along a random order
            keep = rank[src] < rank[dst]
            src, dst = src[keep], dst[keep]
            src, dst = np.concatenate([src, src[:3]]), np.concatenate([dst, dst[:3]])
        start = rng.integers(0, 10, v)
        entered = rng.random(v) < (0.3 if case % 3 == 0 else 0.0)
        got = earliest_first_order(src.astype(np.intp), dst.astype(np.intp), start.astype(np.intp), entered)
        want = reference_order(v, src, dst, start, entered)
        assert np.array_equal(got, want)
        cyclic += bool(want[0] < 0)
    assert 0 < cyclic < 200


def test_detector_order_is_a_topological_order_of_the_plan_graph():
    rng = np.random.default_rng(5)
    _, space, _ = random_instance(rng, 6, ring=True)
    layout = build_segment_layout(space)
    detector = IncrementalCycleDetector(layout, space.initial_labels)
    src, dst = layout.active_edges(space.initial_labels)
    order = np.asarray(detector.order)
    assert sorted(order.tolist()) == list(range(layout.n_nodes)) and np.all(order[src] < order[dst])
