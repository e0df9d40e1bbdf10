"""``--set KEY=VALUE``: scenario fields overridden on the command line.

Each assignment names a field by its dotted path, as a sweep's ``overrides:`` does
(``robots.n=8``, ``teams.0.sigma=0.05``), and gives its value as YAML (``200``, ``0.1``,
``circle``, ``[-5, -5, 5, 5]``, ``{kind: circle, radius: 3}``). The assignments are applied,
in order, to the scenario's mapping before it is validated
(:func:`robofleet.load_scenario` with ``overrides``), so a bad key or value is refused
exactly as it would be in the file, and the message names the ``--set`` argument it came
from.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from ..core.config import is_field_path, parse_yaml
from ..core.errors import ConfigError, ScenarioError, short_repr
from ..scenarios import load_scenario

@dataclass(frozen=True)
class Assignment:
    """One ``--set`` argument: its text as given, the field path and the parsed value."""

    text: str
    key: str
    value: Any

    def __str__(self) -> str:
        return f"--set {self.text}"


def parse_assignment(text: str) -> Assignment:
    """``KEY=VALUE`` as an :class:`Assignment` (VALUE read as YAML; an empty VALUE is ``null``).

    Raises
    ------
    ConfigError
        One line naming the argument: no ``=``, a KEY that is no dotted field path, or a
        VALUE that is no YAML.
    """
    key, equals, raw = text.partition("=")
    key = key.strip()
    if not equals or not is_field_path(key) or any(ch.isspace() for ch in key):
        raise ConfigError(f"--set: expected KEY=VALUE with KEY a dotted field path such as robots.n, received {short_repr(text)}")
    try:
        value = parse_yaml(raw, f"--set {text}")
    except ScenarioError as exc:
        raise ConfigError(f"--set {text}: expected VALUE in YAML (a number, a word, [a, list]), received {short_repr(raw)} "
                          f"({exc.received})") from None
    return Assignment(text, key, value)


def parse_assignments(texts: list[str] | None) -> list[Assignment]:
    """Every ``--set`` argument parsed; a field set twice is refused (as a key given twice in a file is)."""
    assignments = [parse_assignment(text) for text in texts or ()]
    seen: dict[str, Assignment] = {}
    for assignment in assignments:
        if assignment.key in seen:
            raise ConfigError(f"--set: expected each field once, received {assignment.key} twice "
                              f"({seen[assignment.key]} and {assignment})")
        seen[assignment.key] = assignment
    return assignments


def load_with_assignments(scenario: str, texts: list[str] | None):
    """The validated scenario ``scenario`` with the ``--set`` arguments ``texts`` applied.

    Raises
    ------
    ConfigError
        A bad ``--set`` argument, or a scenario that the assignments make invalid: the
        file's own one-line error, prefixed with the ``--set`` arguments it concerns
        (:func:`blamed`).
    ScenarioError
        The scenario file itself is invalid (also without the assignments).
    """
    assignments = parse_assignments(texts)
    if not assignments:
        return load_scenario(scenario)
    try:
        return load_scenario(scenario, overrides={a.key: a.value for a in assignments})
    except ScenarioError as exc:
        raise blamed(exc, assignments, scenario) from None


def blamed(exc: ScenarioError, assignments: list[Assignment], scenario: str) -> ConfigError | ScenarioError:
    """The error to report for ``exc``, raised by the scenario with ``assignments`` applied.

    An index into no element of a list names its assignment. Otherwise the assignments
    whose field is the failing field, lies inside it or holds it are named; when none is,
    the scenario is loaded without them: if it fails alone, its own error is reported (the
    assignments are not to blame), else every assignment is named (together they made the
    scenario invalid, e.g. a layout that no longer fits the workspace).
    """
    indexing = list_index_error(exc, assignments)
    if indexing is not None:
        return indexing
    culprits = [a for a in assignments if overlaps(a.key, exc.field)]
    if not culprits:
        try:
            load_scenario(scenario)
        except ScenarioError as alone:
            return alone
        culprits = assignments
    return ConfigError(f"{' '.join(map(str, culprits))}: {exc}")


def list_index_error(exc: ScenarioError, assignments: list[Assignment]) -> ConfigError | None:
    """``exc`` as the error of the assignment whose numeric part indexes no element of a
    list (:func:`~robofleet.core.config.set_path`, reported under ``overrides KEY``), or ``None``."""
    for assignment in assignments:
        prefix = f"overrides {assignment.key}"
        if exc.field == prefix or exc.field.startswith(prefix + ": "):
            inner = ScenarioError(exc.field[len(prefix) + 2:], exc.expected, exc.received, source=exc.source)
            return ConfigError(f"{assignment}: {inner}")
    return None


def overlaps(key: str, field: str) -> bool:
    """Whether the field path ``key`` is ``field``, lies inside it or holds it
    (``field`` as messages write it: ``robots.layout.starts[0]`` is ``robots.layout.starts.0``)."""
    if not field:
        return False
    parts = re.sub(r"\[(\d+)\]", r".\1", field).split(".")
    keys = key.split(".")
    common = min(len(parts), len(keys))
    return parts[:common] == keys[:common]
