"""The family table and the two public entry points :func:`load_scenario` and :func:`simulate`.

:data:`FAMILIES` maps each ``family:`` key to its :class:`~robofleet.core.family.Family`
(the ``FAMILY`` of ``robofleet/<family>/family.py``). It is the only registry: loading,
the CLI, viz and the conformance suite read it. A fifth family is one more import here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..avoidance.family import FAMILY as AVOIDANCE
from ..coordination.family import FAMILY as COORDINATION
from ..core.budget import check_run_size
from ..core.config import SpecModel, read_mapping, set_path, validate_model
from ..core.errors import ConfigError, InfeasibleError, ScenarioError, short_repr
from ..core.family import Family
from ..core.trace import Trace
from ..flocking.family import FAMILY as FLOCKING
from ..search.family import FAMILY as SEARCH
from . import catalogue

FAMILIES: dict[str, Family] = {f.name: f for f in (AVOIDANCE, COORDINATION, FLOCKING, SEARCH)}
DEFAULT_FAMILY = "avoidance"

ScenarioRef = str | Path | Mapping[str, Any]


def family(name: str, source: str | None = None) -> Family:
    """The :class:`Family` called ``name`` (one-line error naming the valid ones)."""
    if not isinstance(name, str) or name not in FAMILIES:
        raise ScenarioError("family", f"one of {sorted(FAMILIES)}", name, source=source)
    return FAMILIES[name]


def family_of(spec: SpecModel) -> Family:
    """The family a validated spec belongs to."""
    return family(getattr(spec, "family", None))


def read_scenario(ref: ScenarioRef) -> tuple[dict, str | None]:
    """``(mapping, source)`` of a scenario file, shipped name or mapping."""
    if isinstance(ref, Mapping):
        return read_mapping(ref)
    if not isinstance(ref, (str, Path)) or (isinstance(ref, str) and not ref.strip()):
        raise ConfigError(f"scenario: expected a file path, a shipped scenario name or a mapping, received {type(ref).__name__} {short_repr(ref)}")
    return read_mapping(catalogue.resolve(ref))


def load_scenario(ref: ScenarioRef, overrides: Mapping[str, Any] | None = None) -> SpecModel:
    """Read and validate a scenario.

    Parameters
    ----------
    ref:
        A YAML file path, a shipped scenario name (``"avoidance/circle_swap"``, see
        :func:`robofleet.scenarios.list`), or a mapping with the same keys as a file.
    overrides:
        Optional ``{"dotted.field": value}`` applied before validation (used by sweeps).

    Returns
    -------
    The validated, frozen spec of its family; ``spec.source`` is the file it came from
    (``None`` for a mapping).

    Raises
    ------
    ScenarioError
        On the first invalid field, naming the file, field path, expectation and value.
    ConfigError
        When ``ref`` or ``overrides`` are not of a usable type.
    """
    data, source = read_scenario(ref)
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError(f"overrides: expected a mapping {{'dotted.field': value}}, received {type(overrides).__name__} {overrides!r}")
    for key, value in (overrides or {}).items():
        if not isinstance(key, str) or not key or any(not part for part in key.split(".")):
            raise ConfigError(f"overrides: expected dotted field paths such as 'robots.radius' as keys, received {short_repr(key)}")
        try:
            set_path(data, key, value)
        except ScenarioError as exc:
            raise ScenarioError(f"overrides {key}: {exc.field}" if exc.field else f"overrides {key}", exc.expected, exc.received, source=source) from None
    fam = family(data.setdefault("family", DEFAULT_FAMILY), source)
    spec = validate_model(fam.spec, data, source)
    spec._source = source
    check_run_size(spec.run_size(), source)
    return spec


def simulate(scenario: ScenarioRef | SpecModel, seed: int | None = None, progress: bool = False) -> Trace:
    """Run a scenario (a validated spec, or anything :func:`load_scenario` takes).

    ``seed=None`` draws a seed and records it (``trace.seed``);
    ``simulate(spec, seed=trace.seed)`` reproduces every array bit for bit.
    """
    spec = scenario if isinstance(scenario, SpecModel) else load_scenario(scenario)
    fam = FAMILIES.get(getattr(spec, "family", None)) if isinstance(getattr(spec, "family", None), str) else None
    if fam is None or not isinstance(spec, fam.spec):
        raise ConfigError(f"scenario: expected a whole scenario (a family's Spec, as load_scenario returns), received {type(spec).__name__}")
    if not isinstance(progress, (bool, np.bool_)):
        raise ConfigError(f"progress: expected True or False, received {short_repr(progress)}")
    check_run_size(spec.run_size(), spec.source)
    try:
        return fam.simulate(spec, seed=seed, progress=bool(progress))
    except ScenarioError as exc:
        if exc.source is None and spec.source:  # found while running: name the scenario's file
            raise exc.with_source(spec.source) from None
        raise
    except InfeasibleError as exc:  # this file's instance has no solution: name the file (arguments' errors stay as they are)
        if spec.source and not str(exc).startswith(spec.source) and len(exc.args) == 1 and isinstance(exc.args[0], str):
            raise type(exc)(f"{spec.source}: {exc}") from None
        raise
