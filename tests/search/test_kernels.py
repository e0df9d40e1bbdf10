"""The per-step kernels against brute-force all-pairs references on small inputs.

Spatial hashing (:mod:`robofleet.search.neighbours`) must find exactly the pairs an
all-pairs distance matrix finds, in the same order; the collision check must find the
pairs of the all-pairs definition; the block-wise map exchange (:mod:`~robofleet.search.knowledge`)
must equal the one-hop OR of whole maps, step after step; the compiled step pieces
(:mod:`~robofleet.search.step_kernels`) must equal their array definitions.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robofleet.search.knowledge import RobotMaps
from robofleet.search.neighbours import collision_pairs, find_neighbours
from robofleet.search.step_kernels import may_collide, pick_slot


def brute_neighbours(pts, n, alive, rc2, rso2):
    """Dense ``(R, n, n)`` relations from all pairwise distances (the definition)."""
    p = pts.reshape(-1, n, 2)
    diff = p[:, :, None, :] - p[:, None, :, :]
    d2 = np.einsum("rijd,rijd->rij", diff, diff)
    d2[:, np.arange(n), np.arange(n)] = np.inf
    a = alive.reshape(-1, n)
    in_rc, in_rso = d2 <= rc2, d2 <= rso2
    return in_rc & a[:, :, None] & a[:, None, :], in_rso & a[:, :, None], in_rc | in_rso


def dense(table, values, runs):
    out = np.zeros((runs * table.n, table.n), dtype=bool)
    out[table.owner, table.peer % table.n] = values
    return out.reshape(runs, table.n, table.n)


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 4), st.integers(1, 12), st.integers(0, 2**32 - 1), st.floats(0.0, 3.0), st.floats(0.1, 3.0))
def test_spatial_hash_finds_exactly_the_all_pairs_neighbours(runs, n, seed, r_c, r_so):
    rng = np.random.default_rng(seed)
    pts = rng.integers(0, 8, size=(runs * n, 2)) * 0.5  # lattice-like, with shared and boundary distances
    alive = rng.random(runs * n) < 0.8
    rc2, rso2 = (r_c + 1e-9) ** 2, (r_so + 1e-9) ** 2
    table, near = find_neighbours(pts, n, alive, rc2, rso2)
    links, sensed, within = brute_neighbours(pts, n, alive, rc2, rso2)
    np.testing.assert_array_equal(dense(table, table.link, runs), links)
    np.testing.assert_array_equal(dense(table, table.sensed, runs), sensed)
    np.testing.assert_array_equal(dense(table, near, runs), within)
    assert near.all()  # every entry is within one of the ranges
    # entries in the dense (run, i, j) order
    owner = table.owner
    key = owner * runs * n + table.peer
    assert np.all(np.diff(key) > 0) and np.all(owner // n == table.peer // n)


def brute_collisions(pos, choice):
    """The all-pairs definition: same destination, or swapping along one edge (i < j)."""
    same = choice[:, :, None] == choice[:, None, :]
    swap = (choice[:, :, None] == pos[:, None, :]) & (choice[:, None, :] == pos[:, :, None]) & (choice != pos)[:, :, None]
    hit = np.triu(np.ones(same.shape[1:], dtype=bool), k=1) & (same | swap)
    return np.argwhere(hit)


def sorted_pre_check(pos, choice):
    """The array definition of the collision pre-check: a repeated destination in a run, or a
    moving robot's destination occupied in its run."""
    runs = np.arange(pos.shape[0])[:, None]
    dest, here = (runs * 1000 + choice).ravel(), (runs * 1000 + pos).ravel()
    return len(np.unique(dest)) < len(dest) or bool(np.isin(dest[choice.ravel() != pos.ravel()], here).any())


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 4), st.integers(1, 10), st.integers(0, 2**32 - 1), st.integers(2, 12))
def test_collision_pairs_equal_the_all_pairs_definition(runs, n, seed, vertices):
    rng = np.random.default_rng(seed)
    pos = rng.integers(0, vertices, size=(runs, n))
    choice = np.where(rng.random((runs, n)) < 0.5, pos, rng.integers(0, vertices, size=(runs, n)))
    swap = rng.random(runs) < 0.5  # force some swaps
    if n >= 2:
        choice[swap, 0], choice[swap, 1] = pos[swap, 1], pos[swap, 0]
    got = collision_pairs(pos.ravel(), choice.ravel(), n, vertices)
    np.testing.assert_array_equal(got.reshape(-1, 3), brute_collisions(pos, choice).reshape(-1, 3))
    flagged = may_collide(pos.ravel(), choice.ravel(), n)  # the compiled pre-check: its definition, never a miss
    assert flagged == sorted_pre_check(pos, choice)
    assert flagged or len(got) == 0


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 9), st.integers(1, 1500), st.integers(0, 2**32 - 1), st.integers(1, 6))
def test_blockwise_exchange_equals_one_hop_or_of_whole_maps(n, vertices, seed, steps):
    rng = np.random.default_rng(seed)
    maps = RobotMaps(n, vertices, 3)
    reference = np.zeros((n, 4, vertices), dtype=bool)
    targets = np.zeros((n, 3), dtype=bool)
    for _ in range(steps):
        for _ in range(rng.integers(0, 3 * n)):  # private writes (sensing, choices)
            r, layer, v = rng.integers(n), rng.integers(4), rng.integers(vertices)
            maps.set(layer, np.array([r]), np.array([v]))
            reference[r, layer, v] = True
        found = rng.random((n, 3)) < 0.1
        maps.targets |= found
        targets |= found
        links = rng.random((n, n)) < 0.3
        links = links | links.T
        np.fill_diagonal(links, False)
        receivers, senders = np.nonzero(links)
        if len(receivers):
            maps.exchange(receivers, senders)
            reference = reference | (links[:, :, None, None] & reference[None]).any(axis=1)
            targets = targets | (links[:, :, None] & targets[None]).any(axis=1)
        for layer in range(4):
            np.testing.assert_array_equal(maps.as_bool(layer), reference[:, layer])
        np.testing.assert_array_equal(maps.targets, targets)
        open_ = ((reference[:, 1] | reference[:, 0]) & ~reference[:, 3] & ~reference[:, 2]).any(axis=1)
        np.testing.assert_array_equal(maps.frontier_empty(), ~open_)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.booleans(), min_size=1, max_size=8), st.floats(0.0, 1.0, exclude_max=True))
def test_pick_slot_takes_the_floor_of_u_times_the_option_count(pool, u):
    pool = np.array(pool)
    count = int(pool.sum())
    expected = -1 if count == 0 else int(np.flatnonzero(pool)[min(int(u * count), count - 1)])
    assert pick_slot(pool, u) == expected
