"""Checks of arguments passed in code, shared by every public function.

Each returns the value in its normal form or raises a one-line
:class:`~robofleet.core.errors.ConfigError` naming the argument, what was expected and
what was received::

    workers = count(workers, "workers", minimum=1, optional=True)
    progress = flag(progress, "progress")
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ConfigError, short_repr


def flag(value: Any, name: str) -> bool:
    """``value`` as a bool; only ``True``/``False`` (and numpy bools) are accepted."""
    if not isinstance(value, (bool, np.bool_)):
        raise ConfigError(f"{name}: expected True or False, received {short_repr(value)}")
    return bool(value)


def count(value: Any, name: str, *, minimum: int = 0, maximum: int | None = None, optional: bool = False) -> int | None:
    """``value`` as an integer in ``[minimum, maximum]`` (``None`` allowed when ``optional``)."""
    if value is None and optional:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < minimum \
            or (maximum is not None and value > maximum):
        bounds = f"≥ {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
        raise ConfigError(f"{name}: expected an integer {bounds}{' or None' if optional else ''}, received {short_repr(value)}")
    return int(value)


def path(value: Any, name: str, *, optional: bool = False) -> Path | None:
    """``value`` as a :class:`~pathlib.Path` (from a non-empty string or a path)."""
    if value is None and optional:
        return None
    if not isinstance(value, (str, Path)) or not str(value).strip():
        raise ConfigError(f"{name}: expected a path{' or None' if optional else ''}, received {short_repr(value)}")
    return Path(value)


def function(value: Any, name: str) -> Callable:
    """``value`` if it can be called."""
    if not callable(value):
        raise ConfigError(f"{name}: expected a function, received {short_repr(value)}")
    return value


def sequence(value: Any, name: str, what: str) -> list:
    """``value`` (any iterable but a string or a mapping) as a list of ``what``."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Iterable):
        raise ConfigError(f"{name}: expected a list of {what}, received {short_repr(value)}")
    return list(value)


def instance(value: Any, kind: type, name: str, what: str | None = None) -> Any:
    """``value`` if it is a ``kind``."""
    if not isinstance(value, kind):
        raise ConfigError(f"{name}: expected {what or 'a ' + kind.__name__}, received {short_repr(value)}")
    return value
