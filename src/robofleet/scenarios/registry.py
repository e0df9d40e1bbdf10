"""The family table and the two public entry points :func:`load_scenario` and :func:`simulate`.

:data:`FAMILIES` maps each ``family:`` key to its :class:`~robofleet.core.family.Family`
(the ``FAMILY`` of ``robofleet/<family>/family.py``). It is the only registry: loading,
the CLI, viz and the conformance suite read it. A fifth family is one more import here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Mapping

from ..avoidance.family import FAMILY as AVOIDANCE
from ..coordination.family import FAMILY as COORDINATION
from ..core.budget import check_run_size
from ..core.errors import ConfigError, InfeasibleError, ScenarioError, short_repr
from ..core.family import Family
from ..core.lazy import exports
from ..flocking.family import FAMILY as FLOCKING
from ..search.family import FAMILY as SEARCH

if TYPE_CHECKING:
    from ..core.config import ScenarioSource, SpecModel
    from ..core.trace import Trace

FAMILIES: dict[str, Family] = {f.name: f for f in (AVOIDANCE, COORDINATION, FLOCKING, SEARCH)}

__all__ = ["DEFAULT_FAMILY", "FAMILIES", "family", "family_of", "load_scenario", "read_scenario", "simulate"]
# the scenario model's machinery (pydantic, numpy) is imported when a scenario is read, not with the table
__getattr__, __dir__ = exports(__name__, {"robofleet.core.config": ["DEFAULT_FAMILY", "read_scenario"]})


def family(name: str, source: str | None = None) -> Family:
    """The :class:`Family` called ``name`` (one-line error naming the valid ones)."""
    if not isinstance(name, str) or name not in FAMILIES:
        raise ScenarioError("family", f"one of {sorted(FAMILIES)}", name, source=source)
    return FAMILIES[name]


def family_of(spec: SpecModel) -> Family:
    """The family a validated spec belongs to."""
    return family(getattr(spec, "family", None))


def load_scenario(ref: ScenarioSource, overrides: Mapping[str, Any] | None = None) -> SpecModel:
    """Read and validate a scenario.

    Parameters
    ----------
    ref:
        A YAML file path, a shipped scenario name (``"avoidance/circle_swap"``, see
        :func:`robofleet.scenarios.list`), a mapping with the same keys as a file, or a
        validated spec (returned as it is).
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
    from ..core.config import DEFAULT_FAMILY, SOURCE_KINDS, SpecModel, given_spec, scenario_data, spec_from_data

    if isinstance(ref, SpecModel):
        name = getattr(ref, "family", None)
        if not isinstance(name, str) or name not in FAMILIES:
            raise ConfigError(f"scenario: expected {SOURCE_KINDS}, received a {type(ref).__name__} (not a whole scenario)")
        return given_spec(ref, FAMILIES[name].spec, overrides, "scenario")
    data, source = scenario_data(ref, overrides)
    return spec_from_data(family(data.setdefault("family", DEFAULT_FAMILY), source).spec, data, source)


def simulate(scenario: ScenarioSource, seed: int | None = None, progress: bool = False) -> Trace:
    """Run a scenario (a validated spec, or anything :func:`load_scenario` takes).

    ``seed=None`` draws a seed and records it (``trace.seed``);
    ``simulate(spec, seed=trace.seed)`` reproduces every array bit for bit.
    """
    import numpy as np

    from ..core.config import SpecModel
    from ..core.progress import compile_notice

    spec = scenario if isinstance(scenario, SpecModel) else load_scenario(scenario)
    fam = FAMILIES.get(getattr(spec, "family", None)) if isinstance(getattr(spec, "family", None), str) else None
    if fam is None or not isinstance(spec, fam.spec):
        raise ConfigError(f"scenario: expected a whole scenario (a family's Spec, as load_scenario returns), received {type(spec).__name__}")
    if not isinstance(progress, (bool, np.bool_)):
        raise ConfigError(f"progress: expected True or False, received {short_repr(progress)}")
    check_run_size(spec.run_size(), spec.source)
    try:
        with compile_notice(bool(progress)):
            return fam.simulate(spec, seed=seed, progress=bool(progress))
    except ScenarioError as exc:
        if exc.source is None and spec.source:  # found while running: name the scenario's file
            raise exc.with_source(spec.source) from None
        raise
    except InfeasibleError as exc:  # this file's instance has no solution: name the file (arguments' errors stay as they are)
        if spec.source and not str(exc).startswith(spec.source) and len(exc.args) == 1 and isinstance(exc.args[0], str):
            raise type(exc)(f"{spec.source}: {exc}") from None
        raise
