"""The error hierarchy of robofleet.

Every error the library raises on purpose derives from :class:`RobofleetError`, and
each subclass also derives from the builtin a Python user would expect
(``ScenarioError`` is a ``ValueError``), so ``except ValueError`` keeps working.

A message states *where* (file and field path), *what was expected* and *what was
received*, on one line; the CLI prints it as is and exits with status 2.
"""

from __future__ import annotations

from typing import Any


class RobofleetError(Exception):
    """Base class of every error raised on purpose by robofleet."""


class ScenarioError(RobofleetError, ValueError):
    """A scenario, sweep or data file is invalid.

    Parameters
    ----------
    field:
        Dotted path of the offending field (``"robots.radius"``), or ``""``.
    expected:
        What a valid value looks like.
    received:
        The value that was given (shown with ``repr``, shortened).
    source:
        The file the value came from, or ``None`` for in-memory input.
    """

    def __init__(self, field: str, expected: str, received: Any = None, *, source: str | None = None):
        self.field = field
        self.expected = expected
        self.received = received
        self.source = source
        super().__init__(self._format())

    def _format(self) -> str:
        where = str(self.source) if self.source else "<mapping>"
        if self.field:
            where += f": {self.field}"
        return f"{where}: expected {self.expected}, received {short_repr(self.received)}"

    def with_source(self, source: str) -> "ScenarioError":
        """Return a copy of this error that names ``source`` as its file."""
        return ScenarioError(self.field, self.expected, self.received, source=source)


class ConfigError(RobofleetError, ValueError):
    """A parameter passed in code is invalid (same message form as ScenarioError)."""


class InfeasibleError(RobofleetError, RuntimeError):
    """An instance has no solution the algorithm can find (e.g. an unreachable goal)."""


class TraceError(RobofleetError, ValueError):
    """A trace file is missing, corrupt or of an unknown version."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep: a ``KeyboardInterrupt`` whose message says how many runs
    the store holds and how to resume."""


class Described(str):
    """A received value given as a description (``"8 robots × 500 steps ≈ 1 MiB"``),
    shown in messages without quotes."""

    def __repr__(self) -> str:
        return str(self)


def one_line(exc: BaseException, limit: int = 160) -> str:
    """An exception's message on one line, cut to ``limit`` characters (its type's name if it has none)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def short_repr(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (twice that for a :class:`Described`), on one line."""
    limit = 2 * limit if isinstance(value, Described) else limit
    text = repr(value).replace("\n", " ")
    return text if len(text) <= limit else text[: limit - 3] + "..."
