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
from typing import Union

import numpy as np

from .errors import ConfigError, short_repr

RngLike = Union[int, np.random.SeedSequence, np.random.Generator, None]
MAX_SEED = 2**63 - 1


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

    Uses ``SeedSequence(root).spawn(n)``; the integers are stored with every result row
    so that a single run can be replayed with ``seed=row["seed"]``.
    """
    root = resolve_seed(root, "root")
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ConfigError(f"n: expected a non-negative integer count of seeds, received {short_repr(n)}")
    children = np.random.SeedSequence(root).spawn(int(n))
    return [int(c.generate_state(2, dtype=np.uint64)[0] >> np.uint64(1)) for c in children]


def keyed_generator(seed: int, *keys: int | str) -> np.random.Generator:
    """A generator for the stream identified by ``(seed, *keys)``.

    Used where several methods must see *identical* random events, e.g. one stream per
    (seed, robot, step) for disturbances: the draw depends only on the key, never on how
    many draws other robots or methods made before.
    """
    words = [resolve_seed(seed, "seed")]
    for key in keys:
        if isinstance(key, (bool, np.bool_)) or not isinstance(key, (str, int, np.integer)):
            raise ConfigError(f"keys: expected integers or strings, received {short_repr(key)}")
        if isinstance(key, str):
            words.append(int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest(), "little"))
        else:
            words.append(int(key) & (2**63 - 1))
    return np.random.default_rng(np.random.SeedSequence(words))
