"""Random number generation: one normalisation point, no global state.

Every stochastic entry point of robofleet takes ``rng`` (an int, a
``numpy.random.SeedSequence``, a ``numpy.random.Generator`` or ``None``) and passes it
through :func:`as_generator` once.
"""

from __future__ import annotations

import hashlib
from typing import Union

import numpy as np

RngLike = Union[int, np.random.SeedSequence, np.random.Generator, None]


def as_generator(rng: RngLike = None) -> np.random.Generator:
    """Normalise ``rng`` to a ``numpy.random.Generator`` (``default_rng`` semantics)."""
    if isinstance(rng, (bool, np.bool_)):
        raise TypeError(f"rng: expected int, SeedSequence, Generator or None, received {rng!r}")
    return np.random.default_rng(rng)


def spawn_seeds(root: int, n: int) -> list[int]:
    """``n`` independent 63-bit integer seeds derived from ``root``.

    Uses ``SeedSequence(root).spawn(n)``; the integers are stored with every result row
    so that a single run can be replayed with ``seed=row["seed"]``.
    """
    children = np.random.SeedSequence(root).spawn(n)
    return [int(c.generate_state(2, dtype=np.uint64)[0] >> np.uint64(1)) for c in children]


def keyed_generator(seed: int, *keys: int | str) -> np.random.Generator:
    """A generator for the stream identified by ``(seed, *keys)``.

    Used where several methods must see *identical* random events, e.g. one stream per
    (seed, robot, step) for disturbances: the draw depends only on the key, never on how
    many draws other robots or methods made before.
    """
    words = [int(seed) & (2**63 - 1)]
    for key in keys:
        if isinstance(key, str):
            words.append(int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest(), "little"))
        else:
            words.append(int(key) & (2**63 - 1))
    return np.random.default_rng(np.random.SeedSequence(words))
