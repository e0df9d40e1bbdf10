"""Config objects shared by every layer: the strict pydantic base :class:`SpecModel`,
YAML reading, the translation of validation failures into one-line
:class:`~robofleet.core.errors.ScenarioError` s, and the one way to turn a scenario
source (a shipped name, a file, a mapping or a spec) into a validated spec
(:func:`load_spec`; :func:`robofleet.load_scenario` is the same for any family).

Dynamics, algorithms and scenario specs all build their parameter objects on
:class:`SpecModel` (frozen, keyword-only, unknown keys are errors), so nothing below the
scenario layer has to import it.
"""

from __future__ import annotations

import copy
import math
from collections import abc
from pathlib import Path
from typing import Any, Mapping, TypeVar

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, PrivateAttr, ValidationError, model_validator
from pydantic.fields import FieldInfo

from . import catalogue
from .budget import RunSize, check_run_size
from .errors import ConfigError, Described, RobofleetError, ScenarioError, short_repr

_Model = TypeVar("_Model", bound=BaseModel)

YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""libyaml's safe loader where PyYAML was built with it (about 10× faster), else PyYAML's."""


MAX_MAGNITUDE = 1e9
"""The largest magnitude any number of a spec may have (integers too, unless their field
declares its own upper bound, as seeds do): far beyond every sensible length, time,
speed or count here, and far below where float arithmetic loses metres."""

MAX_VALUES = 2_000_000
"""The most values (numbers, strings, lists, mappings; shared ones counted each time they
appear) a scenario or sweep may hold: far beyond every sensible file, and a bound on the
work validation does (a YAML alias "bomb" expands past it at once)."""


class SpecModel(BaseModel):
    """Base of every scenario model: frozen, keyword-only, unknown keys are errors, NaN
    and ±inf are refused where a number is expected, and every number in it (fields, and
    lists or mappings of numbers) has a magnitude of at most :data:`MAX_MAGNITUDE`
    (integers: unless the field declares its own upper bound, as seeds do)."""

    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True, allow_inf_nan=False)
    _source: str | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _finite_numbers(self) -> "SpecModel":
        for name, info in type(self).model_fields.items():
            bad = first_unreasonable_number(getattr(self, name), name, integer_limit(info))
            if bad is not None:
                raise ScenarioError(bad[0], f"a finite number of magnitude at most {MAX_MAGNITUDE:g}", bad[1])
        return self

    @model_validator(mode="after")
    def _fits_memory(self) -> SpecModel:
        # before the family's own cross-checks (parent validators run first), so that a
        # scenario too big to run is refused before its layout of a billion robots is checked
        check_run_size(self.run_size())
        return self

    @property
    def source(self) -> str | None:
        """The file this scenario was loaded from (``None`` for a mapping)."""
        return self._source

    @property
    def scenario_name(self) -> str:
        """The scenario's ``name`` field, else its file's stem, else ``""``."""
        name = getattr(self, "name", "")
        return str(name) if name else (Path(self._source).stem if self._source else "")

    def run_size(self) -> RunSize | None:
        """What a run of this scenario holds (steps × robots × bytes; see
        :mod:`robofleet.core.budget`), checked against the memory budget when the scenario
        is loaded; ``None`` for models that are not a whole scenario."""
        return None


def integer_limit(info: FieldInfo) -> float | None:
    """The largest integer magnitude a field accepts: its own upper bound (``le``/``lt``)
    if it declares one, none for an untyped (``Any``) field, else :data:`MAX_MAGNITUDE`."""
    if info.annotation is Any:
        return None
    if any(getattr(m, "le", None) is not None or getattr(m, "lt", None) is not None for m in info.metadata):
        return None
    return MAX_MAGNITUDE


def first_unreasonable_number(value: Any, path: str, integer_limit: float | None = None) -> tuple[str, Any] | None:
    """``(field path, number)`` of the first NaN, infinite or huge number in ``value``
    (a number, or nested lists, tuples, mappings and arrays of them); nested spec models
    check themselves. Integers are checked against ``integer_limit`` (``None``: any size)."""
    if isinstance(value, (bool, np.bool_, str, BaseModel)) or value is None:
        return None
    if isinstance(value, (int, np.integer)):
        return None if integer_limit is None or abs(int(value)) <= integer_limit else (path, value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return None if math.isfinite(number) and abs(number) <= MAX_MAGNITUDE else (path, value)
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(value) | (np.abs(value) > MAX_MAGNITUDE))
        return None if not len(bad) else (f"{path}[{bad[0]}]", value.flat[bad[0]])
    items = value.items() if isinstance(value, Mapping) else enumerate(value) if isinstance(value, (list, tuple)) else ()
    for key, item in items:
        found = first_unreasonable_number(item, f"{path}.{key}" if isinstance(value, Mapping) else f"{path}[{key}]", integer_limit)
        if found is not None:
            return found
    return None


class StrictYAMLLoader(YAML_LOADER):
    """The safe loader, refusing a key given twice in one mapping (YAML would keep the last)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                key = self.construct_object(key_node)
                if key in seen:
                    raise yaml.constructor.ConstructorError(None, None, f"the key {key!r} given twice", key_node.start_mark)
                seen.add(key)
        return super().construct_mapping(node, deep)


def read_mapping(path_or_mapping: str | Path | Mapping[str, Any]) -> tuple[dict, str | None]:
    """Return ``(mapping, source)`` from a YAML file path or an in-memory mapping.

    Raises
    ------
    ScenarioError
        Naming the file: unreadable, not UTF-8 text, not YAML (a duplicate key, an integer
        of thousands of digits, nesting too deep), not a mapping at the top level, or
        holding more than :data:`MAX_VALUES` values.
    """
    if isinstance(path_or_mapping, Mapping):
        check_value_count(path_or_mapping, None)
        return copy.deepcopy(dict(path_or_mapping)), None
    path = Path(path_or_mapping)
    source = str(path)
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ScenarioError("", "a UTF-8 text file", Described(f"a byte {exc.object[exc.start:exc.start + 1]!r} at offset {exc.start} that is not UTF-8"),
                            source=source) from None
    except OSError as exc:
        raise ScenarioError("", "a readable YAML file", f"{type(exc).__name__}: {exc.strerror}", source=source) from None
    except ValueError as exc:  # a path the system cannot look up (a NUL byte)
        raise ScenarioError("", "a readable YAML file", str(exc), source=short_repr(source, 60)) from None
    data = parse_yaml(text, source)
    if not isinstance(data, dict):
        raise ScenarioError("", "a mapping at the top level", type(data).__name__, source=source)
    check_value_count(data, source)
    return data, source


def parse_yaml(text: str, source: str) -> Any:
    """The YAML document ``text``, or a one-line :class:`ScenarioError` naming the line."""
    try:
        return yaml.load(text, Loader=StrictYAMLLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark else ""
        problem = str(getattr(exc, "problem", None) or exc).splitlines()[0]
        raise ScenarioError(where, "valid YAML", problem, source=source) from None
    except (ValueError, RecursionError) as exc:  # an integer of thousands of digits, nesting beyond the stack
        raise ScenarioError("", "valid YAML of reasonable size", str(exc).split(";")[0], source=source) from None


CONTAINERS = (dict, list, tuple, abc.Mapping)


def check_value_count(data: Any, source: str | None, limit: int = MAX_VALUES) -> None:
    """Refuse data holding more than ``limit`` values, counting shared (aliased) values
    each time they appear (each shared part is sized once), and data that contains itself."""
    sizes: dict[int, int] = {}  # values under each container, itself included
    inside: set[int] = set()
    stack: list[tuple[Any, bool]] = [(data, False)]
    while stack:
        node, leaving = stack.pop()
        key = id(node)
        children = list(node.values()) if isinstance(node, (dict, abc.Mapping)) else node
        if leaving:
            inside.discard(key)
            sizes[key] = 1 + sum(sizes.get(id(child), 1) for child in children)
            if sizes[key] > limit:
                raise ScenarioError("", f"at most {limit:,} values (counting every alias expansion)", Described("more"), source=source)
            continue
        if key in sizes:
            continue
        if key in inside:
            raise ScenarioError("", "data that does not contain itself", Described("a recursive alias"), source=source)
        inside.add(key)
        stack.append((node, True))
        stack.extend((child, False) for child in children if isinstance(child, CONTAINERS) and id(child) not in sizes)


def validate_model(model: type[_Model], data: Mapping[str, Any], source: str | None) -> _Model:
    """Validate ``data`` with ``model``; turn the first failure into a :class:`ScenarioError`.

    Validators see the file the data came from as ``info.context["source"]`` (``None``
    for a mapping), so they can read files a scenario names relative to it.
    """
    try:
        return model.model_validate(data, context={"source": source})
    except ValidationError as exc:
        inner = (exc.errors(include_url=False)[0].get("ctx") or {}).get("error")
        if isinstance(inner, RobofleetError) and not isinstance(inner, ScenarioError):
            raise inner from None  # not about the data (a bad ROBOFLEET_MEMORY_BUDGET): as raised
        raise scenario_error_from(exc, source) from None


def scenario_error_from(exc: ValidationError, source: str | None) -> ScenarioError:
    """One-line error from the first entry of a pydantic ``ValidationError``."""
    err = exc.errors(include_url=False)[0]
    loc = ".".join(str(p) for p in err["loc"])
    inner = (err.get("ctx") or {}).get("error")
    if isinstance(inner, ScenarioError):
        if inner.source and inner.source != source:  # a file the scenario names (a plan, a pattern)
            return ScenarioError(": ".join(p for p in (loc, inner.source, inner.field) if p), inner.expected, inner.received, source=source)
        field = ".".join(p for p in (loc, inner.field) if p)
        return ScenarioError(field, inner.expected, inner.received, source=source)
    if err["type"] == "extra_forbidden":
        return ScenarioError(loc, "no such key (unknown field)", err.get("input"), source=source)
    if err["type"] == "missing":
        return ScenarioError(loc, "this required field", "nothing", source=source)
    expected = err["msg"]
    for prefix in ("Value error, ", "Input should be "):
        if expected.startswith(prefix):
            expected = expected[len(prefix):]
    return ScenarioError(loc, expected, err.get("input"), source=source)


def is_field_path(key: Any) -> bool:
    """Whether ``key`` is a dotted field path such as ``robots.radius`` (no empty part)."""
    return isinstance(key, str) and bool(key) and all(part for part in key.split("."))


def set_path(mapping: dict, dotted: str, value: Any) -> None:
    """Set ``mapping["a"]["b"] = value`` for ``dotted == "a.b"`` (creating sub-mappings).

    A numeric part indexes an existing list: ``teams.0.sigma`` sets the first team's
    ``sigma``.

    Raises
    ------
    ScenarioError
        If a numeric part names no element of the list there.
    """
    keys = dotted.split(".")
    node: Any = mapping
    for depth, key in enumerate(keys[:-1]):
        if isinstance(node, list):
            node = list_element(node, key, ".".join(keys[:depth]))
            continue
        nxt = node.get(key)
        if not isinstance(nxt, (dict, list)):
            nxt = node[key] = {}
        node = nxt
    if isinstance(node, list):
        node[list_index(node, keys[-1], ".".join(keys[:-1]))] = value
    else:
        node[keys[-1]] = value


def list_index(items: list, key: str, where: str) -> int:
    """``int(key)`` if it indexes ``items``, else a one-line :class:`ScenarioError`."""
    if not key.isdigit() or int(key) >= len(items):
        raise ScenarioError(where, f"an index below {len(items)} into this list", key)
    return int(key)


def list_element(items: list, key: str, where: str) -> Any:
    """The element of ``items`` that ``key`` indexes, made a mapping if it is not one."""
    index = list_index(items, key, where)
    if not isinstance(items[index], (dict, list)):
        items[index] = {}
    return items[index]


def as_array(value: Any, shape_tail: tuple[int, ...], field: str) -> np.ndarray:
    """A finite float64 array whose trailing shape is ``shape_tail`` (``-1`` = any)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ScenarioError(field, f"numbers shaped (..., {', '.join(map(str, shape_tail))})", value) from None
    tail = arr.shape[len(arr.shape) - len(shape_tail):] if arr.ndim >= len(shape_tail) else None
    if tail is None or any(e != -1 and e != t for e, t in zip(shape_tail, tail)):
        raise ScenarioError(field, f"an array shaped (..., {', '.join('*' if e == -1 else str(e) for e in shape_tail)})", f"shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ScenarioError(field, "finite numbers", value)
    return arr


# ---------------------------------------------------------------------------------------
# scenario sources
# ---------------------------------------------------------------------------------------
ScenarioSource = str | Path | Mapping[str, Any] | SpecModel
"""What every function and object built from a scenario accepts: a shipped scenario name
(``"avoidance/circle_swap"``), a YAML file, a mapping with a file's keys, or a validated spec."""

DEFAULT_FAMILY = "avoidance"
"""The family of a scenario file or mapping without a ``family:`` key."""

SOURCE_KINDS = "a shipped scenario name, a YAML file, a mapping or a validated spec"


def read_scenario(ref: str | Path | Mapping[str, Any], argument: str = "scenario") -> tuple[dict, str | None]:
    """``(mapping, source)`` of a scenario file, shipped name or mapping (a file that
    exists wins over a shipped name, :func:`~.catalogue.resolve`).

    Raises
    ------
    ConfigError
        Naming ``argument`` when ``ref`` is none of those kinds (a number, ``None``, a blank string).
    ScenarioError
        Naming the file when it cannot be read (or no shipped scenario has that name).
    """
    if isinstance(ref, Mapping):
        return read_mapping(ref)
    if not isinstance(ref, (str, Path)) or (isinstance(ref, str) and not ref.strip()):
        raise ConfigError(f"{argument}: expected {SOURCE_KINDS}, received {type(ref).__name__} {short_repr(ref)}")
    return read_mapping(catalogue.resolve(ref))


def scenario_data(ref: str | Path | Mapping[str, Any], overrides: Mapping[str, Any] | None = None,
                  argument: str = "scenario") -> tuple[dict, str | None]:
    """:func:`read_scenario` with ``{"dotted.field": value}`` overrides applied."""
    data, source = read_scenario(ref, argument)
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError(f"overrides: expected a mapping {{'dotted.field': value}}, received {type(overrides).__name__} {short_repr(overrides)}")
    for key, value in (overrides or {}).items():
        if not is_field_path(key):
            raise ConfigError(f"overrides: expected dotted field paths such as 'robots.radius' as keys, received {short_repr(key)}")
        try:
            set_path(data, key, value)
        except ScenarioError as exc:
            raise ScenarioError(f"overrides {key}: {exc.field}" if exc.field else f"overrides {key}", exc.expected, exc.received, source=source) from None
    return data, source


def spec_from_data(model: type[_Model], data: Mapping[str, Any], source: str | None) -> _Model:
    """``data`` validated by ``model``, remembering its file, checked against the memory budget."""
    spec = validate_model(model, data, source)
    spec._source = source
    check_run_size(spec.run_size(), source)
    return spec


def family_name(model: type[SpecModel]) -> str:
    """The family a scenario model belongs to (its ``family`` field's value, by the family contract)."""
    return str(model.model_fields["family"].default)


def a_scenario_of(family: str) -> str:
    """``"an avoidance scenario"``, ``"a search scenario"``."""
    return f"{'an' if family[:1] in tuple('aeiou') else 'a'} {family} scenario"


def given_spec(spec: SpecModel, model: type[_Model], overrides: Mapping[str, Any] | None, argument: str) -> _Model:
    """A spec passed as a scenario source: itself, if it is a ``model`` and no overrides are asked for."""
    if not isinstance(spec, model):
        family = getattr(spec, "family", None)
        received = f"a {family} scenario spec" if isinstance(family, str) else f"a {type(spec).__name__} (not a whole scenario)"
        raise ConfigError(f"{argument}: expected {a_scenario_of(family_name(model))} ({SOURCE_KINDS}), received {received}")
    if overrides is not None:
        raise ConfigError(f"overrides: expected None for a validated spec (apply overrides to its file, name or mapping), "
                          f"received {short_repr(overrides)}")
    return spec


def load_spec(source: ScenarioSource, model: type[_Model], overrides: Mapping[str, Any] | None = None, *,
              argument: str = "scenario") -> _Model:
    """One family's validated scenario from any scenario source: the one way every object
    built from a scenario (the safety filter, the environments, the supervisor) reads it.

    Parameters
    ----------
    source: the scenario (its shipped name, its YAML file, a mapping with a file's keys,
        or the validated ``model`` itself, returned as it is).
    model: the family's ``Spec``.
    overrides: optional ``{"dotted.field": value}`` applied before validation (not with a spec).
    argument: the caller's parameter name, for the messages.

    Raises
    ------
    ConfigError
        One line naming ``argument``: a source of no accepted kind, or a scenario of another family.
    ScenarioError
        One line naming the file and field: an unreadable file or an invalid field.
    """
    if isinstance(source, SpecModel):
        return given_spec(source, model, overrides, argument)
    data, file = scenario_data(source, overrides, argument)
    wanted, found = family_name(model), data.get("family", DEFAULT_FAMILY)
    if found != wanted:
        where = file if file is not None else "a mapping"
        family = f"of family {short_repr(found)}" if "family" in data else f"without a family: key (so of family {DEFAULT_FAMILY!r})"
        raise ConfigError(f"{argument}: expected {a_scenario_of(wanted)} ({SOURCE_KINDS}), received {where} {family}")
    return spec_from_data(model, data, file)
