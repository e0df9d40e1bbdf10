"""Config objects shared by every layer: the strict pydantic base :class:`SpecModel`,
YAML reading, and the translation of validation failures into one-line
:class:`~robofleet.core.errors.ScenarioError` s.

Dynamics, algorithms and scenario specs all build their parameter objects on
:class:`SpecModel` (frozen, keyword-only, unknown keys are errors), so nothing below the
scenario layer has to import it.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any, Mapping, TypeVar

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, PrivateAttr, ValidationError, model_validator

from .errors import ScenarioError

_Model = TypeVar("_Model", bound=BaseModel)

YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""libyaml's safe loader where PyYAML was built with it (about 10× faster), else PyYAML's."""


MAX_MAGNITUDE = 1e9
"""The largest magnitude any real number of a spec may have: far beyond every sensible
length, time or speed here, and far below where float arithmetic loses metres."""


class SpecModel(BaseModel):
    """Base of every scenario model: frozen, keyword-only, unknown keys are errors, and
    every number in it (fields, and lists or mappings of numbers) is finite with a
    magnitude of at most :data:`MAX_MAGNITUDE` (integers: any size)."""

    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True)
    _source: str | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _finite_numbers(self) -> "SpecModel":
        for name in type(self).model_fields:
            bad = first_unreasonable_number(getattr(self, name), name)
            if bad is not None:
                raise ScenarioError(bad[0], f"a finite number of magnitude at most {MAX_MAGNITUDE:g}", bad[1])
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


def first_unreasonable_number(value: Any, path: str) -> tuple[str, Any] | None:
    """``(field path, number)`` of the first NaN, infinite or huge number in ``value``
    (a number, or nested lists, tuples, mappings and arrays of them); nested spec models
    check themselves."""
    if isinstance(value, (bool, np.bool_, str, BaseModel)) or value is None:
        return None
    if isinstance(value, (int, np.integer)):
        return None  # integers (counts, seeds up to 2**63) are exact and always finite
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return None if math.isfinite(number) and abs(number) <= MAX_MAGNITUDE else (path, value)
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(value) | (np.abs(value) > MAX_MAGNITUDE))
        return None if not len(bad) else (f"{path}[{bad[0]}]", value.flat[bad[0]])
    items = value.items() if isinstance(value, Mapping) else enumerate(value) if isinstance(value, (list, tuple)) else ()
    for key, item in items:
        found = first_unreasonable_number(item, f"{path}.{key}" if isinstance(value, Mapping) else f"{path}[{key}]")
        if found is not None:
            return found
    return None


def read_mapping(path_or_mapping: str | Path | Mapping[str, Any]) -> tuple[dict, str | None]:
    """Return ``(mapping, source)`` from a YAML file path or an in-memory mapping."""
    if isinstance(path_or_mapping, Mapping):
        return copy.deepcopy(dict(path_or_mapping)), None
    path = Path(path_or_mapping)
    source = str(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ScenarioError("", "a readable YAML file", f"{type(exc).__name__}: {exc.strerror}", source=source) from None
    try:
        data = yaml.load(text, Loader=YAML_LOADER)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark else ""
        raise ScenarioError(where, "valid YAML", str(getattr(exc, "problem", exc)), source=source) from None
    if not isinstance(data, dict):
        raise ScenarioError("", "a mapping at the top level", type(data).__name__, source=source)
    return data, source


def validate_model(model: type[_Model], data: Mapping[str, Any], source: str | None) -> _Model:
    """Validate ``data`` with ``model``; turn the first failure into a :class:`ScenarioError`.

    Validators see the file the data came from as ``info.context["source"]`` (``None``
    for a mapping), so they can read files a scenario names relative to it.
    """
    try:
        return model.model_validate(data, context={"source": source})
    except ValidationError as exc:
        raise scenario_error_from(exc, source) from None


def scenario_error_from(exc: ValidationError, source: str | None) -> ScenarioError:
    """One-line error from the first entry of a pydantic ``ValidationError``."""
    err = exc.errors(include_url=False)[0]
    loc = ".".join(str(p) for p in err["loc"])
    inner = (err.get("ctx") or {}).get("error")
    if isinstance(inner, ScenarioError):
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
