"""The robots' streams and the sweep's seeds are numpy's: ``keyed_generator`` and
``spawn_seeds`` (whose states are hashed by compiled code) against ``SeedSequence``."""

from __future__ import annotations

import hashlib
import pickle
import random

import numpy as np

from robofleet.core.rng import HashedSeedSequence, keyed_generator, spawn_seeds
from robofleet.core.seed_sequence import assembled_entropy, state_of


def reference_generator(seed: int, *keys) -> np.random.Generator:
    """The stream's definition: ``default_rng(SeedSequence([seed, *words]))``."""
    words = [seed]
    for key in keys:
        if isinstance(key, str):
            words.append(int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest(), "little"))
        else:
            words.append(int(key) & (2**63 - 1))
    return np.random.default_rng(np.random.SeedSequence(words))


def test_state_words_equal_seed_sequence_for_random_entropy_and_spawn_keys():
    rng = random.Random(22)
    for _ in range(2000):
        entropy = [rng.choice([0, 1, rng.getrandbits(31), rng.getrandbits(63), rng.getrandbits(64), rng.getrandbits(130)])
                   for _ in range(rng.randint(1, 7))]
        spawn_key = tuple(rng.choice([0, 7, rng.getrandbits(32), rng.getrandbits(45)]) for _ in range(rng.randint(0, 3)))
        expected = np.random.SeedSequence(entropy, spawn_key=spawn_key).generate_state(6, np.uint64)
        assert np.array_equal(state_of(assembled_entropy(entropy, spawn_key), 6), expected), (entropy, spawn_key)


def test_keyed_generators_draw_numpys_streams_and_spawn_alike():
    rng = random.Random(7)
    for seed in [0, 1, 2017, 2**63 - 1, *(rng.getrandbits(63) for _ in range(20))]:
        for keys in [(), ("search-robot", rng.randrange(64)), ("search-starts",), ("disturbance", 3, rng.getrandbits(40))]:
            ours, theirs = keyed_generator(seed, *keys), reference_generator(seed, *keys)
            assert np.array_equal(ours.random(300), theirs.random(300))
            assert np.array_equal(ours.standard_normal((50, 3)), theirs.standard_normal((50, 3)))
            assert np.array_equal(ours.integers(0, 1000, 40), theirs.integers(0, 1000, 40))
            for a, b in zip(ours.spawn(2) + ours.spawn(1), theirs.spawn(2) + theirs.spawn(1)):
                assert np.array_equal(a.random(5), b.random(5))
    generator = keyed_generator(5, "x")
    assert np.array_equal(pickle.loads(pickle.dumps(generator)).random(4), generator.random(4))


def test_hashed_seed_sequence_states_in_both_word_sizes():
    ours, theirs = HashedSeedSequence([5, 2**70 + 3]), np.random.SeedSequence([5, 2**70 + 3])
    for n in (1, 2, 3, 4, 9):
        assert np.array_equal(ours.generate_state(n), theirs.generate_state(n))
        assert np.array_equal(ours.generate_state(n, np.uint64), theirs.generate_state(n, np.uint64))


def test_spawned_seeds_are_the_seed_sequence_childrens_words():
    for root, n in [(0, 3), (2017, 500), (2**63 - 1, 40), (123456789012, 1), (9, 0)]:
        children = np.random.SeedSequence(root).spawn(n)
        assert spawn_seeds(root, n) == [int(c.generate_state(2, dtype=np.uint64)[0] >> np.uint64(1)) for c in children]
        assert all(type(s) is int for s in spawn_seeds(root, n))
