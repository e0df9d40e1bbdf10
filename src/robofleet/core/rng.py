"""Random number generation: one seed rule, one normalisation point, no global state.

The seed rule (in the spirit of Gymnasium's ``utils.seeding``): every run entry point
(``simulate(spec, seed=None)`` of each family) passes its ``seed`` through
:func:`resolve_seed` once. ``None`` draws a fresh seed from the operating system's
entropy; either way the run uses, and records in its trace, the integer it got, so
``simulate(spec, seed=trace.seed)`` replays every array bit for bit. Anything that is
not a non-negative integer below 2**63 is refused with a one-line
:class:`~robofleet.core.errors.ConfigError`.

Lower-level stochastic functions take ``rng`` (an int, a ``numpy.random.SeedSequence``,
a ``numpy.random.Generator`` or ``None``) and pass it through :func:`as_generator` once.
"""

from __future__ import annotations

import hashlib
import sys
from typing import Union

import numpy as np
from numpy.random.bit_generator import ISpawnableSeedSequence

from .errors import ConfigError, short_repr

RngLike = Union[int, np.random.SeedSequence, np.random.Generator, None]
MAX_SEED = 2**63 - 1
COMPILED_SPAWN = 10_000
"""From this many seeds on, :func:`spawn_seeds` hashes them in compiled code even in a
process that has not loaded numba yet."""


def resolve_seed(seed: object = None, where: str = "seed") -> int:
    """The integer seed a run uses: ``seed`` itself, or a fresh one drawn when ``None``.

    Parameters
    ----------
    seed:
        ``None`` or an integer in ``[0, 2**63)`` (Python or numpy integer; ``bool`` is refused).
    where:
        The name shown in the error message.

    Returns
    -------
    int
        The seed; record it (``Trace.seed``) so the run can be replayed.

    Raises
    ------
    ConfigError
        For anything else (strings, floats, negative numbers, generators...).
    """
    if seed is None:
        return int(np.random.SeedSequence().entropy) & MAX_SEED
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) <= MAX_SEED:
        raise ConfigError(f"{where}: expected a non-negative integer below 2**63 or None, received {short_repr(seed)}")
    return int(seed)


def as_generator(rng: RngLike = None) -> np.random.Generator:
    """Normalise ``rng`` to a ``numpy.random.Generator`` (``default_rng`` semantics).

    Raises
    ------
    ConfigError
        For anything but ``None``, a non-negative integer, a ``SeedSequence`` or a ``Generator``.
    """
    if isinstance(rng, (np.random.Generator, np.random.SeedSequence)) or rng is None:
        return np.random.default_rng(rng)
    if isinstance(rng, (bool, np.bool_)) or not isinstance(rng, (int, np.integer)) or int(rng) < 0:
        raise ConfigError(f"rng: expected a non-negative integer, a SeedSequence, a Generator or None, received {short_repr(rng)}")
    return np.random.default_rng(int(rng))


def spawn_seeds(root: int, n: int) -> list[int]:
    """``n`` independent 63-bit integer seeds derived from ``root``.

    Seed ``i`` is the first 64-bit state word of the ``i``-th child of
    ``SeedSequence(root).spawn(n)``, shifted right by one bit (computed by
    :mod:`robofleet.core.seed_sequence`, the same words); the integers are stored with
    every result row so that a single run can be replayed with ``seed=row["seed"]``.
    """
    root = resolve_seed(root, "root")
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ConfigError(f"n: expected a non-negative integer count of seeds, received {short_repr(n)}")
    if n < COMPILED_SPAWN and "numba" not in sys.modules:  # a few seeds: not worth loading numba
        children = np.random.SeedSequence(root).spawn(int(n))
        return [int(c.generate_state(2, dtype=np.uint64)[0] >> np.uint64(1)) for c in children]
    from .seed_sequence import assembled_entropy, spawned_first_words  # compiled: loaded on first use

    return (spawned_first_words(assembled_entropy([root]), int(n)) >> np.uint64(1)).tolist()


def keyed_generator(seed: int, *keys: int | str) -> np.random.Generator:
    """A generator for the stream identified by ``(seed, *keys)``.

    Used where several methods must see *identical* random events, e.g. one stream per
    (seed, robot, step) for disturbances: the draw depends only on the key, never on how
    many draws other robots or methods made before. The stream is that of
    ``numpy.random.default_rng(SeedSequence([seed, *words]))``, a string key's word being
    its 64-bit BLAKE2b hash (the state hashed by :class:`HashedSeedSequence`).
    """
    words = [resolve_seed(seed, "seed")]
    for key in keys:
        if isinstance(key, (bool, np.bool_)) or not isinstance(key, (str, int, np.integer)):
            raise ConfigError(f"keys: expected integers or strings, received {short_repr(key)}")
        if isinstance(key, str):
            words.append(int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest(), "little"))
        else:
            words.append(int(key) & (2**63 - 1))
    return np.random.Generator(np.random.PCG64(HashedSeedSequence(words)))


class HashedSeedSequence(ISpawnableSeedSequence):
    """``numpy.random.SeedSequence(entropy)`` whose states are hashed by compiled code
    (:mod:`robofleet.core.seed_sequence`: the same words, a microsecond instead of tens);
    it spawns children as ``SeedSequence(entropy)`` does."""

    def __init__(self, entropy: list[int]):
        self.entropy = entropy
        self._sequence: np.random.SeedSequence | None = None

    def generate_state(self, n_words: int, dtype: type = np.uint32) -> np.ndarray:
        """``SeedSequence(entropy).generate_state(n_words, dtype)`` (``uint32`` or ``uint64`` words);
        numpy's own hashing until numba is loaded (a process that never simulates need not load it)."""
        if "numba" not in sys.modules:
            return np.random.SeedSequence(self.entropy).generate_state(n_words, dtype)
        from .seed_sequence import assembled_entropy, state_of  # compiled: loaded on first use

        if np.dtype(dtype) == np.uint64:
            return state_of(assembled_entropy(self.entropy), int(n_words))
        if np.dtype(dtype) != np.uint32:
            raise ConfigError(f"dtype: expected numpy.uint32 or numpy.uint64, received {short_repr(dtype)}")
        words = state_of(assembled_entropy(self.entropy), -(-int(n_words) // 2))
        return words.astype("<u8").view("<u4")[: int(n_words)].astype(np.uint32)

    def spawn(self, n_children: int) -> list[np.random.SeedSequence]:
        """``SeedSequence(entropy).spawn(n_children)`` (children numbered on from earlier spawns)."""
        if self._sequence is None:
            self._sequence = np.random.SeedSequence(self.entropy)
        return self._sequence.spawn(n_children)
