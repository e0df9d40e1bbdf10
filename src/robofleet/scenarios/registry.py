"""Scenario families and the two public entry points :func:`load_scenario` and
:func:`simulate`.

A family is a module ``robofleet.<family>.scenario`` that defines

* ``Spec``: the pydantic model of a validated scenario (a :class:`SpecModel` with a
  ``family: Literal["<family>"]`` field), and
* ``simulate(spec, seed=None, progress=False) -> Trace``.

Modules are imported lazily, so loading one family never imports another.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any, Mapping

from ..core.errors import ScenarioError
from ..core.rng import RngLike
from ..core.trace import Trace
from .base import read_mapping, set_path, validate_model

FAMILIES: dict[str, str] = {
    "avoidance": "robofleet.avoidance.scenario",
    "coordination": "robofleet.coordination.scenario",
    "flocking": "robofleet.flocking.scenario",
    "search": "robofleet.search.scenario",
}
DEFAULT_FAMILY = "avoidance"


def family_module(name: str, source: str | None = None):
    """The module implementing family ``name``."""
    if name not in FAMILIES:
        raise ScenarioError("family", f"one of {sorted(FAMILIES)}", name, source=source)
    return importlib.import_module(FAMILIES[name])


def load_scenario(path_or_mapping: str | Path | Mapping[str, Any], overrides: Mapping[str, Any] | None = None):
    """Read and validate a scenario.

    Parameters
    ----------
    path_or_mapping:
        A YAML file path, or a mapping with the same keys as the file.
    overrides:
        Optional ``{"dotted.field": value}`` applied before validation (used by sweeps).

    Returns
    -------
    The validated, frozen scenario model of its family. Its ``source`` attribute holds
    the file it came from (or ``None``).

    Raises
    ------
    ScenarioError
        On the first invalid field, naming the file, field path, expectation and value.
    """
    data, source = read_mapping(path_or_mapping)
    for key, value in (overrides or {}).items():
        set_path(data, key, value)
    family = data.setdefault("family", DEFAULT_FAMILY)
    module = family_module(family, source)
    spec = validate_model(module.Spec, data, source)
    spec._source = source
    return spec


def simulate(scenario, seed: RngLike = None, progress: bool = False) -> Trace:
    """Run a validated scenario (or a path/mapping, loaded first) and return its :class:`Trace`.

    The same ``seed`` always gives the same trace.
    """
    if not hasattr(scenario, "family") or isinstance(scenario, (str, Path, Mapping)):
        scenario = load_scenario(scenario)
    return family_module(scenario.family).simulate(scenario, seed=seed, progress=progress)
