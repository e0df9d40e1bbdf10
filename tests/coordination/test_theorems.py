"""Paper 000's guarantees as tests: Figs. 2/3/5, Theorems 1, 2 and 4, RMTRACK safety, and
agreement of the incremental and the reference cycle tests."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from coordination_instances import fig2_example, random_instance
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.label_flipping import KnownProbabilities
from robofleet.coordination.segment_graph import (
    IncrementalCycleDetector, Resolution, build_segment_layout, find_cycle_nodes, has_cycle_full,
)
from robofleet.coordination.plan_execution import PlanExecutor, Method, Variant

SEEDS = st.integers(0, 2**32 - 1)


def executor(traj, space, check, flip_test, layout=None, p=0.3, **kw):
    prob = np.full(traj.positions.shape[:2], p)
    return PlanExecutor(traj, space, Variant(Method.TFF, check), KnownProbabilities(prob, traj.dt), prob,
                    layout=layout, flip_test=flip_test, **kw)


# ---------------------------------------------------------------- Figs. 2, 3 and 5
def fig5_run(check: bool):
    traj = fig2_example()
    space = build_coordination_space(traj)
    only_robot0_vs_1 = lambda ctx: (ctx.waiter, ctx.other) == (0, 1)  # noqa: E731
    robot1_disturbed = lambda t, x: np.array([False, t < 60, False])  # noqa: E731
    return executor(traj, space, check, only_robot0_vs_1, p=0.0, disturbed=robot1_disturbed, record_cycles=True).run(0, 2000)


def test_fig2_plan_labels_and_overlapping_segments():
    traj = fig2_example()
    space = build_coordination_space(traj)
    pairs = {(int(i), int(j)): int(lab) for i, j, lab in zip(space.robot_i, space.robot_j, space.initial_labels)}
    assert pairs == {(0, 1): 1, (0, 2): 2, (1, 2): 1}


def test_fig3_flip_closes_a_cycle_in_the_segment_graph():
    traj = fig2_example()
    space = build_coordination_space(traj)
    layout = build_segment_layout(space)
    start = np.zeros(3, dtype=int)
    assert not has_cycle_full(layout, space.initial_labels, start)
    flipped = space.initial_labels.copy()
    flipped[0] = 0  # ℓ(o_01) := robot 0 (Fig. 3 right)
    cycle = find_cycle_nodes(layout, flipped, start)
    assert set(layout.node_robot[cycle].tolist()) == {0, 1, 2}
    detector = IncrementalCycleDetector(layout, space.initial_labels)
    assert not detector.try_flip(0, 0)
    assert np.array_equal(detector.labels, space.initial_labels)


def test_fig5_flip_deadlocks_without_check():
    run = fig5_run(check=False)
    assert run.flips == 1 and run.deadlock and not run.finished
    first_cycle = int(np.argmax(run.cycle_log))
    flip_step = next(e["step"] for e in run.events if e["kind"] == "flip")
    assert run.cycle_log[first_cycle] and first_cycle == flip_step
    deadlock = next(e for e in run.events if e["kind"] == "deadlock")
    assert sorted(deadlock["robots"]) == [0, 1, 2]
    assert run.collisions == 0


def test_fig5_flip_refused_with_check():
    run = fig5_run(check=True)
    assert run.flips == 0 and run.refused_flips == 1
    assert run.finished and not run.deadlock and run.collisions == 0
    assert not any(run.cycle_log)


# ---------------------------------------------------------------- Theorems 1 and 2
def random_flipper(seed: int, layout, probability: float = 0.5):
    """Flip at random, but never once the active subgraph already has a cycle
    (Theorem 2 speaks of the system as it is, without later label changes)."""
    rng = np.random.default_rng(seed)

    def test(ctx):
        if has_cycle_full(layout, ctx.labels, ctx.progress):
            return False
        return bool(rng.random() < probability)

    return test


def deadlock_iff_cycle(seed: int, n_robots: int, ring: bool = True):
    rng = np.random.default_rng(seed)
    traj, space, layout = random_instance(rng, n_robots, ring=ring)
    flipper = random_flipper(seed, layout, 0.8)
    run = executor(traj, space, False, flipper, layout=layout, record_cycles=True).run(seed, 5000)
    log = np.asarray(run.cycle_log)
    assert run.collisions == 0
    assert run.deadlock or run.finished, "ran into the step limit"
    if run.deadlock:  # Theorem 1: deadlock ⇒ cycle in the active subgraph
        assert log[-1]
    if log.any():  # Theorem 2: cycle ⇒ deadlock (labels frozen once a cycle exists)
        assert run.deadlock
        assert log[np.argmax(log):].all()
    return run


@settings(max_examples=250, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(3, 7), ring=st.booleans())
def test_theorems_1_2_deadlock_iff_active_cycle(seed, n_robots, ring):
    deadlock_iff_cycle(seed, n_robots, ring)


def test_random_flips_do_deadlock_sometimes():
    """The property test is not vacuous: random flips deadlock in some instances."""
    outcomes = [deadlock_iff_cycle(seed, 6).deadlock for seed in range(40)]
    assert 0 < sum(outcomes) < len(outcomes)


# ---------------------------------------------------------------- Theorem 4
@settings(max_examples=60, deadline=None, derandomize=True)
@given(seed=SEEDS)
def test_theorem4_disjoint_segments_never_deadlock(seed):
    rng = np.random.default_rng(seed)
    traj, space, layout = random_instance(rng, 4, size=16.0, disjoint=True)
    run = executor(traj, space, False, lambda ctx: True, layout=layout, p=0.5, record_cycles=True).run(seed, 5000)
    assert run.finished and not run.deadlock and not any(run.cycle_log)
    assert run.collisions == 0


# ---------------------------------------------------------------- safety of the checked variants
@settings(max_examples=80, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(3, 7), p=st.sampled_from([0.0, 0.3, 0.8]))
def test_checked_flips_never_collide_or_deadlock(seed, n_robots, p):
    rng = np.random.default_rng(seed)
    traj, space, layout = random_instance(rng, n_robots)
    flips = np.random.default_rng(seed + 1)
    for check, flip_test in ((True, lambda ctx: bool(flips.random() < 0.7)), (True, lambda ctx: True)):
        run = executor(traj, space, check, flip_test, layout=layout, p=p).run(seed, 5000)
        assert run.finished and not run.deadlock and run.collisions == 0


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(2, 6), p=st.sampled_from([0.0, 0.5, 0.9]))
def test_rmtrack_never_collides_or_deadlocks(seed, n_robots, p):
    rng = np.random.default_rng(seed)
    traj, space, _ = random_instance(rng, n_robots)
    prob = np.full(traj.positions.shape[:2], p)
    run = PlanExecutor(traj, space, Variant(Method.RMTRACK, False), KnownProbabilities(prob, traj.dt), prob).run(seed, 20000)
    assert run.finished and not run.deadlock and run.collisions == 0 and run.flips == 0


# ---------------------------------------------------------------- incremental == full
class ComparingDetector(IncrementalCycleDetector):
    """Checks every incremental answer against the full rebuild at the current progress."""

    progress = None
    compared = refused = 0

    def try_flip(self, obstacle, new_label, progress=None):
        assert progress is not None and np.array_equal(progress, self.progress)
        tentative = self.labels.copy()
        tentative[obstacle] = new_label
        expected = not has_cycle_full(self.layout, tentative, progress)
        got = super().try_flip(obstacle, new_label, progress)
        assert got == expected
        type(self).compared += 1
        type(self).refused += not got
        return got


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(3, 6), resolution=st.sampled_from(list(Resolution)))
def test_incremental_and_full_cycle_tests_agree(seed, n_robots, resolution):
    rng = np.random.default_rng(seed)
    traj, space, _ = random_instance(rng, n_robots, ring=bool(seed % 2))
    layout = build_segment_layout(space, resolution)

    def flip_test(ctx):
        ComparingDetector.progress = ctx.progress
        return True

    run = executor(traj, space, True, flip_test, layout=layout, p=0.5, detector=ComparingDetector).run(seed, 5000)
    assert run.finished and not run.deadlock


def test_incremental_comparison_is_exercised():
    ComparingDetector.compared = ComparingDetector.refused = 0
    for seed in range(40):
        test_incremental_and_full_cycle_tests_agree.hypothesis.inner_test(2 * seed + 1, 7, Resolution.EXACT)
    assert ComparingDetector.compared > 10 and ComparingDetector.refused > 0


def test_theorem4_needs_flips_at_the_entrance():
    """Three robots circling a triangle of crossings: disjoint collision segments, yet a
    label assignment that no entrance flip can produce closes a cycle (see guarantees.py)."""
    from coordination_instances import line
    from robofleet.coordination.guarantees import check_theory
    from robofleet.coordination.trajectories import make_trajectories

    a, b, c = np.array([0.0, 0.0]), np.array([20.0, 0.0]), np.array([10.0, 17.0])
    paths = [line(b + 0.5 * (b - a), a - 0.5 * (b - a), 0.25),            # robot 0: B then A
             line(a - 0.5 * (c - a), c + 0.5 * (c - a), 0.25, 300),       # robot 1: A then C
             line(c - 0.5 * (b - c), b + 0.5 * (b - c), 0.25, 600)]       # robot 2: C then B
    traj = make_trajectories(paths, 1.0, 0.1)
    space = build_coordination_space(traj)
    report = check_theory(traj, space)
    assert report.non_conflicting and report.disjoint_segments and space.n_obstacles == 3
    layout = build_segment_layout(space)
    start = np.zeros(3, dtype=int)
    assert not has_cycle_full(layout, space.initial_labels, start)
    labels = space.initial_labels.copy()
    pair = {(int(i), int(j)): k for k, (i, j) in enumerate(zip(space.robot_i, space.robot_j))}
    labels[pair[(0, 1)]], labels[pair[(1, 2)]], labels[pair[(0, 2)]] = 0, 1, 2  # A: 0 first, C: 1 first, B: 2 first
    assert has_cycle_full(layout, labels, start)
