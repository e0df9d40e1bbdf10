"""numpy's ``SeedSequence`` hashing as compiled code: the same states, without the object.

``numpy.random.SeedSequence(entropy, spawn_key)`` turns integers into a bit generator's
initial state in three steps (O'Neill's ``seed_seq_fe`` with a pool of 4 words): the
integers are split into little-endian 32-bit words (``entropy`` first, padded to the
pool size when a spawn key follows, then ``spawn_key``); the words are hashed into the
pool (:func:`mix_entropy`); the pool is hashed again into the state words
(:func:`generate_state`). Each step costs numpy some ten microseconds of Python-level
work, which a run spends once per robot stream and a sweep once per seed;
here it is one compiled call. :mod:`robofleet.core.rng` imports this module on first use
(so that importing robofleet does not load numba) and its tests compare every result
with ``SeedSequence``'s.
"""

from __future__ import annotations

import numba
import numpy as np

POOL_SIZE = 4
U = np.uint64  # every word is held in 64 bits and masked to 32 after each operation
INIT_A, MULT_A = U(0x43B0D7E5), U(0x931E8875)
INIT_B, MULT_B = U(0x8B51F9DD), U(0x58F38DED)
MIX_MULT_L, MIX_MULT_R = U(0xCA01F9DD), U(0x4973F715)
MASK32 = U(0xFFFFFFFF)
XSHIFT = U(16)
HIGH = U(32)


def uint32_words(value: int) -> list[int]:
    """The little-endian 32-bit words of a non-negative integer (``[0]`` for zero)."""
    words = [value & 0xFFFFFFFF]
    value >>= 32
    while value:
        words.append(value & 0xFFFFFFFF)
        value >>= 32
    return words


def assembled_entropy(entropy: list[int], spawn_key: tuple[int, ...] = ()) -> np.ndarray:
    """The 32-bit words ``SeedSequence(entropy, spawn_key=spawn_key)`` hashes into its pool."""
    run = [w for value in entropy for w in uint32_words(value)]
    spawn = [w for value in spawn_key for w in uint32_words(value)]
    if spawn and len(run) < POOL_SIZE:
        run += [0] * (POOL_SIZE - len(run))
    return np.array(run + spawn, dtype=np.uint64)


@numba.njit(cache=True)
def hashmix(value, hash_const):
    """One hash of a word; returns it and the advanced hash constant (32-bit arithmetic)."""
    value = (value ^ hash_const) & MASK32
    hash_const = (hash_const * MULT_A) & MASK32
    value = (value * hash_const) & MASK32
    return value ^ (value >> XSHIFT), hash_const


@numba.njit(cache=True)
def mix(x, y):
    """Two pool words combined."""
    result = (MIX_MULT_L * x - MIX_MULT_R * y) & MASK32
    return result ^ (result >> XSHIFT)


@numba.njit(cache=True)
def mix_entropy(entropy):
    """The pool of 4 words hashed from the assembled entropy words."""
    pool = np.zeros(POOL_SIZE, np.uint64)
    hash_const = INIT_A
    for i in range(POOL_SIZE):
        word = entropy[i] if i < len(entropy) else U(0)
        pool[i], hash_const = hashmix(word, hash_const)
    for i_src in range(POOL_SIZE):
        for i_dst in range(POOL_SIZE):
            if i_src != i_dst:
                hashed, hash_const = hashmix(pool[i_src], hash_const)
                pool[i_dst] = mix(pool[i_dst], hashed)
    for i_src in range(POOL_SIZE, len(entropy)):
        for i_dst in range(POOL_SIZE):
            hashed, hash_const = hashmix(entropy[i_src], hash_const)
            pool[i_dst] = mix(pool[i_dst], hashed)
    return pool


@numba.njit(cache=True)
def generate_state(pool, n_words64):
    """``n_words64`` 64-bit state words from the pool (``generate_state(n, np.uint64)``)."""
    out = np.empty(n_words64, np.uint64)
    hash_const = INIT_B
    for i in range(2 * n_words64):
        value = (pool[i % POOL_SIZE] ^ hash_const) & MASK32
        hash_const = (hash_const * MULT_B) & MASK32
        value = (value * hash_const) & MASK32
        value ^= value >> XSHIFT
        if i % 2 == 0:
            out[i // 2] = value
        else:
            out[i // 2] |= value << HIGH
    return out


@numba.njit(cache=True)
def state_of(entropy, n_words64):
    """``SeedSequence`` state words of the assembled ``entropy`` (:func:`assembled_entropy`)."""
    return generate_state(mix_entropy(entropy), n_words64)


@numba.njit(cache=True)
def spawned_first_words(root_words, n):
    """The first 64-bit state word of each of ``SeedSequence(root).spawn(n)``'s children:
    child ``i`` hashes the root's words padded to the pool size, then ``i``'s words."""
    out = np.empty(n, np.uint64)
    base = max(len(root_words), POOL_SIZE)
    for i in range(n):
        key = U(i)
        extra = 1 if key <= MASK32 else 2
        entropy = np.zeros(base + extra, np.uint64)
        entropy[:len(root_words)] = root_words
        entropy[base] = key & MASK32
        if extra == 2:
            entropy[base + 1] = key >> HIGH
        out[i] = generate_state(mix_entropy(entropy), 1)[0]
    return out
