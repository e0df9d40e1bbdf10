"""Config objects shared by every layer: the strict pydantic base :class:`SpecModel`,
YAML reading, and the translation of validation failures into one-line
:class:`~robofleet.core.errors.ScenarioError` s.

Dynamics, algorithms and scenario specs all build their parameter objects on
:class:`SpecModel` (frozen, keyword-only, unknown keys are errors), so nothing below the
scenario layer has to import it.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, PrivateAttr, ValidationError

from .errors import ScenarioError


class SpecModel(BaseModel):
    """Base of every scenario model: frozen, keyword-only, unknown keys are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True)
    _source: str | None = PrivateAttr(default=None)

    @property
    def source(self) -> str | None:
        """The file this scenario was loaded from (``None`` for a mapping)."""
        return self._source

    @property
    def scenario_name(self) -> str:
        """The scenario's ``name`` field, else its file's stem, else ``""``."""
        name = getattr(self, "name", "")
        return str(name) if name else (Path(self._source).stem if self._source else "")


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
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark else ""
        raise ScenarioError(where, "valid YAML", str(getattr(exc, "problem", exc)), source=source) from None
    if not isinstance(data, dict):
        raise ScenarioError("", "a mapping at the top level", type(data).__name__, source=source)
    return data, source


def validate_model(model: type[BaseModel], data: Mapping[str, Any], source: str | None):
    """Validate ``data`` with ``model``; turn the first failure into a :class:`ScenarioError`."""
    try:
        return model.model_validate(data)
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
    """Set ``mapping["a"]["b"] = value`` for ``dotted == "a.b"`` (creating sub-mappings)."""
    keys = dotted.split(".")
    node = mapping
    for key in keys[:-1]:
        nxt = node.get(key)
        if not isinstance(nxt, dict):
            nxt = node[key] = {}
        node = nxt
    node[keys[-1]] = value


def as_array(value, shape_tail: tuple[int, ...], field: str) -> np.ndarray:
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
