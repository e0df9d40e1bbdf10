"""Coordination space against a dense brute force; Eq. 1; flip tests; expected times."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from coordination_instances import line, random_instance
from robofleet.core.errors import InfeasibleError
from robofleet.coordination.coordination_space import build_coordination_space, obstacle_grid, pair_cells, space_of_cells
from robofleet.coordination.label_flipping import (
    FlipContext, KnownProbabilities, LearnedProbabilities, flip_eligible, pair_rollout, tfa_wants_flip, tff_wants_flip,
)
from robofleet.coordination.rmtrack import ActionRule
from robofleet.coordination.segment_graph import Resolution, build_segment_layout, has_cycle_full
from robofleet.coordination.trajectories import Trajectories, make_trajectories

SEEDS = st.integers(0, 2**32 - 1)


def dense_obstacles(traj):
    """(i, j, cells) of every 4-connected component of every pair's dense grid."""
    out = []
    four = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]])
    for i in range(traj.n_robots):
        for j in range(i + 1, traj.n_robots):
            lab, k = ndimage.label(obstacle_grid(traj, i, j), structure=four)
            for c in range(1, k + 1):
                out.append((i, j, np.argwhere(lab == c)))
    return out


def key(i, j, cells):
    return (i, j, int(cells[:, 0].min()), int(cells[:, 1].min()), len(cells))


def space_key(space, k):
    return (int(space.robot_i[k]), int(space.robot_j[k]), int(space.side_lo[2 * k]), int(space.side_lo[2 * k + 1]),
            int(space.n_cells[k]))


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(2, 6), window=st.sampled_from([4, 7, 32]))
def test_space_matches_dense_grid(seed, n_robots, window):
    traj, _, _ = random_instance(np.random.default_rng(seed), n_robots, ring=bool(seed % 2))
    space = build_coordination_space(traj, window=window)
    dense = {key(*o): o for o in dense_obstacles(traj)}
    assert space.n_obstacles == len(dense)
    for k in range(space.n_obstacles):
        i, j, lo_i, lo_j, _ = space_key(space, k)
        _, _, cells = dense[space_key(space, k)]
        assert space.side_hi[2 * k] == cells[:, 0].max() and space.side_hi[2 * k + 1] == cells[:, 1].max()
        top = [cells[cells[:, 0] == c, 1].max() for c in range(lo_i, int(space.side_hi[2 * k]) + 1)]
        right = [cells[cells[:, 1] == r, 0].max() for r in range(lo_j, int(space.side_hi[2 * k + 1]) + 1)]
        assert np.array_equal(space.side_profile(2 * k), top)
        assert np.array_equal(space.side_profile(2 * k + 1), right)
        first = i if np.all(cells[:, 0] < cells[:, 1]) else j
        assert space.initial_labels[k] == first


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=SEEDS, n_robots=st.integers(2, 6))
def test_eq1_matches_line_test_on_dense_grid(seed, n_robots):
    rng = np.random.default_rng(seed)
    traj, space, _ = random_instance(rng, n_robots, ring=True)
    rule = ActionRule(space)
    dense = dense_obstacles(traj)
    for _ in range(30):
        x = rng.integers(0, traj.lengths + 1)
        labels = np.where(rng.random(space.n_obstacles) < 0.5, space.robot_i, space.robot_j)
        waiting, moving, finished = rule.states(labels, x)
        expected = np.zeros(n_robots, dtype=bool)
        index = {space_key(space, k): k for k in range(space.n_obstacles)}
        for i, j, cells in dense:
            lab = labels[index[key(i, j, cells)]]
            w, a, col, row = (i, j, 0, 1) if lab == j else (j, i, 1, 0)
            line_hit = np.any((cells[:, col] == x[w] + 1) & (cells[:, row] >= x[a]))
            expected[w] |= bool(line_hit)
        expected &= x < traj.lengths
        assert np.array_equal(waiting, expected)
        assert np.array_equal(finished, x >= traj.lengths)
        assert np.array_equal(moving, ~waiting & ~finished)


def test_plan_collision_is_refused():
    paths = [line((-5, 0), (5, 0), 0.5), line((0, -5), (0, 5), 0.5)]
    with pytest.raises(InfeasibleError, match="robots 0 and 1"):
        build_coordination_space(make_trajectories(paths, 1.0, 0.1))


def test_far_apart_robots_have_no_obstacles():
    paths = [line((0, 0), (10, 0), 0.5), line((0, 50), (10, 50), 0.5)]
    traj = make_trajectories(paths, 1.0, 0.1)
    space = build_coordination_space(traj)
    assert space.n_obstacles == 0
    layout = build_segment_layout(space)
    assert not has_cycle_full(layout, space.initial_labels, np.zeros(2, int))


# ---------------------------------------------------------------- flip tests
def crossing(p_waiter: float, p_other: float, delay_other: int):
    """Robot 0 crosses robot 1's path; robot 1 passes first in the plan."""
    paths = [line((-6, 0), (6, 0), 0.25, 30), line((0, -6), (0, 6), 0.25, delay_other)]
    traj = make_trajectories(paths, 1.0, 0.1)
    space = build_coordination_space(traj)
    prob = np.stack([np.full(traj.positions.shape[1], p_waiter), np.full(traj.positions.shape[1], p_other)])
    return traj, space, KnownProbabilities(prob, 0.1)


def waiting_context(traj, space, times, x_other):
    side = space.side_of(0, 0)
    assert space.initial_labels[0] == 1
    x = np.array([space.side_lo[side] - 1, x_other])
    assert ActionRule(space).states(space.initial_labels, x)[0][0]
    return FlipContext(space, side, 0, 1, x, times, space.initial_labels)


def test_tff_flips_when_the_other_robot_is_slow_and_far():
    traj, space, times = crossing(0.05, 0.9, 0)
    ctx = waiting_context(traj, space, times, 0)
    assert tff_wants_flip(ctx) and tfa_wants_flip(ctx)
    assert flip_eligible(space, ctx.side, ctx.progress, np.zeros(1, bool))


def test_no_flip_when_the_other_robot_is_about_to_pass():
    traj, space, times = crossing(0.3, 0.05, 0)
    side = space.side_of(0, 0)
    ctx = waiting_context(traj, space, times, int(space.side_other_lo[side]) - 1)
    assert not tff_wants_flip(ctx) and not tfa_wants_flip(ctx)


def test_tfa_is_more_aggressive_than_tff():
    """Waiter at the entrance, the other robot two steps away, equal probabilities: only TFA flips
    (letting the closer robot through first lowers the pair's total; TFF needs the waiter to clear first)."""
    traj, space, times = crossing(0.05, 0.05, 0)
    side = space.side_of(0, 0)
    ctx = waiting_context(traj, space, times, int(space.side_other_lo[side]) - 2)
    assert tfa_wants_flip(ctx) and not tff_wants_flip(ctx)


def test_flip_not_eligible_once_the_other_robot_is_inside():
    traj, space, times = crossing(0.05, 0.9, 0)
    side = space.side_of(0, 0)
    x = np.array([space.side_lo[side] - 1, space.side_other_lo[side]])
    assert not flip_eligible(space, side, x, np.zeros(1, bool))
    x[1] -= 1
    assert flip_eligible(space, side, x, np.zeros(1, bool))
    assert not flip_eligible(space, side, x, np.ones(1, bool))  # at most once per obstacle


def test_pair_rollout_expected_times():
    """Undisturbed pair (p clipped to 0.05): each robot needs Δ/0.95 per step; with the
    flipped label the waiter clears first, exactly after its remaining steps."""
    traj, space, times = crossing(0.0, 0.0, 0)
    ctx = waiting_context(traj, space, times, 0)
    w_flip, a_flip = pair_rollout(ctx, first=0)
    steps_w = space.side_hi[ctx.side] + 1 - ctx.progress[0]
    assert w_flip == pytest.approx(steps_w * 0.1 / 0.95)
    w_keep, a_keep = pair_rollout(ctx, first=1)
    assert a_keep == pytest.approx((space.side_hi[ctx.side ^ 1] + 1) * 0.1 / 0.95)
    assert w_keep > w_flip and a_flip >= a_keep  # the other robot is far: the flip costs it nothing


def test_expected_time_is_geometric():
    times = KnownProbabilities(np.array([[0.0, 0.5, 0.75, 0.0]]), 0.1)
    assert times.expected_time(0, 0, 3) == pytest.approx(0.1 + 0.2 + 0.4)
    assert times.expected_time(0, 2, 1) == 0.0


def test_learned_estimate_converges_to_frequency():
    rng = np.random.default_rng(0)
    cells = np.zeros((1, 5), dtype=int)
    learned = LearnedProbabilities(cells, 1, 0.1, prior=0.05)
    for _ in range(4000):
        learned.observe(np.array([0]), np.array([True]), np.array([rng.random() < 0.6]))
    assert learned.estimate()[0] == pytest.approx(0.6, abs=0.03)
    assert learned.expected_time(0, 0, 2) == pytest.approx(2 * 0.1 / (1 - learned.estimate()[0]))


def test_definition3_graph_is_coarser_than_exact():
    """Every cycle of the exact graph is one of the literal Definition 3 graph (it only adds constraints)."""
    for seed in range(15):
        rng = np.random.default_rng(seed)
        traj, space, _ = random_instance(rng, 6, ring=True)
        exact, coarse = build_segment_layout(space), build_segment_layout(space, Resolution.DEFINITION3)
        for _ in range(10):
            labels = np.where(rng.random(space.n_obstacles) < 0.5, space.robot_i, space.robot_j)
            x = np.zeros(traj.n_robots, int)
            if has_cycle_full(exact, labels, x):
                assert has_cycle_full(coarse, labels, x)


@pytest.mark.parametrize("seed", range(6))
def test_a_space_from_carried_pair_cells_is_the_full_build(seed):
    """After one robot's plan is cut or extended, the other pairs' cells carried over with
    that robot's pairs recomputed give exactly the space of a full build (what a
    supervisor's plan change relies on)."""
    rng = np.random.default_rng(seed)
    traj, _, _ = random_instance(rng, 4, ring=True)
    cells = pair_cells(traj)
    i = int(rng.integers(traj.n_robots))
    positions, lengths = traj.positions.copy(), traj.lengths.copy()
    if seed % 2:  # cut: the robot parks at a step of its plan
        step = int(rng.integers(0, lengths[i] + 1))
        positions[i, step + 1:], lengths[i] = positions[i, step], step
    else:  # extended: the robot walks its path back to its start, through the others' paths
        back, goal = positions[i, lengths[i] - 1::-1], lengths[i]
        positions = np.concatenate([positions, np.repeat(positions[:, -1:], len(back), axis=1)], axis=1)
        positions[i, goal + 1: goal + 1 + len(back)] = back
        positions[i, goal + 1 + len(back):] = back[-1]
        lengths[i] += len(back)
    changed = Trajectories(positions, lengths, traj.radius, traj.dt)
    carried = {pair: c for pair, c in cells.items() if i not in pair}
    carried.update(pair_cells(changed, robot=i))
    full = build_coordination_space(changed, check_plan=False)
    built = space_of_cells(changed, carried, check_plan=False)
    for name in [f.name for f in dataclasses.fields(full)]:
        assert np.array_equal(getattr(built, name), getattr(full, name)), name
