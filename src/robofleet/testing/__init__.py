"""A public conformance checker for families and scenarios (in the spirit of Gymnasium's
``utils.env_checker``): what every family must satisfy to be part of robofleet.

>>> from robofleet.testing import check_scenario
>>> check_scenario("avoidance/circle_swap", steps=3)  # doctest: +SKIP

For one scenario at a tiny step budget, :func:`check_scenario` checks that

1. it validates, and its family is in the family table;
2. the same seed gives identical arrays, events, metadata and results (timings aside);
3. ``seed=None`` draws a seed, records it as ``trace.seed``, and
   ``simulate(spec, seed=trace.seed)`` replays the run exactly;
4. ``Trace.save`` / ``Trace.load`` round-trips every array and the summary;
5. the summary is strict JSON of scalars starting with the core keys
   (:data:`~robofleet.core.trace.CORE_SUMMARY_KEYS`) with the right types;
6. the family's ``check`` returns :class:`~robofleet.core.family.Guarantee` s;
7. (``figures=True``) the family's ``plot_trace`` and ``animate_trace`` write non-empty files.

:func:`check_family` runs it over every shipped scenario of a family. A new family passes
it or it is not done.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ..core.config import SpecModel
from ..core import arguments
from ..core.errors import ConfigError, RobofleetError, short_repr
from ..core.rng import resolve_seed
from ..core.family import Family, Guarantee
from ..core.trace import CORE_SUMMARY_KEYS, Trace, dumps_json
from ..scenarios import FAMILIES, catalogue, family_of, load_scenario

TIMING_SUFFIX = "_seconds"
CORE_TYPES: dict[str, tuple[type, ...]] = {
    "family": (str,), "scenario": (str,), "seed": (int,), "success": (bool,),
    "n_robots": (int,), "n_steps": (int,), "wall_seconds": (float, int),
}


class ConformanceError(RobofleetError, AssertionError):
    """A family or scenario breaks the family contract; the message lists every failure."""


def check_scenario(ref: str | Path | SpecModel, *, steps: int = 5, seed: int = 7, figures: bool = True,
                   workdir: str | Path | None = None) -> Trace:
    """Run the conformance checks on one scenario at a budget of ``steps`` steps.

    Returns the checked trace; raises :class:`ConformanceError` listing every failed check.
    """
    check_arguments(steps, seed, figures)
    spec = ref if isinstance(ref, SpecModel) else load_scenario(ref)
    family = family_of(spec)
    spec = load_scenario(spec.source if spec.source else spec.model_dump(mode="json"), {family.budget: steps})
    failures: list[str] = []
    first = family.simulate(spec, seed=seed)
    failures += compare_traces(first, family.simulate(spec, seed=seed), "same seed twice")
    if first.seed != seed:
        failures.append(f"trace.seed is {first.seed!r}, expected the seed passed ({seed})")
    drawn = family.simulate(spec, seed=None)
    if not isinstance(drawn.metadata.get("seed"), int):
        failures.append(f"seed=None: trace.seed is {drawn.metadata.get('seed')!r}, expected the drawn integer")
    else:
        failures += compare_traces(drawn, family.simulate(spec, seed=drawn.seed), "seed=None replayed from trace.seed")
    failures += check_summary(first, family)
    failures += check_guarantees(family, spec)
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        failures += check_round_trip(first, Path(tmp) / "trace")
        if figures:
            failures += check_figures(first, family, Path(tmp))
    if failures:
        name = spec.source or spec.scenario_name or family.name
        raise ConformanceError(f"{name}: " + "; ".join(failures))
    return first


def check_family(name: str, *, steps: int = 5, seed: int = 7, figures: bool = True) -> list[str]:
    """:func:`check_scenario` on every shipped scenario of family ``name``; returns their names."""
    if not isinstance(name, str) or name not in FAMILIES:
        raise ConfigError(f"name: expected one of {sorted(FAMILIES)}, received {short_repr(name)}")
    check_arguments(steps, seed, figures)
    checked = [e.name for e in catalogue.list() if e.family == name]
    for entry in checked:
        check_scenario(entry, steps=steps, seed=seed, figures=figures)
    return checked


def check_arguments(steps: Any, seed: Any, figures: Any) -> None:
    """The shared arguments of :func:`check_scenario` and :func:`check_family`."""
    arguments.count(steps, "steps", minimum=1)
    resolve_seed(seed, "seed")
    arguments.flag(figures, "figures")


def compare_traces(a: Trace, b: Trace, what: str) -> list[str]:
    """Differences between two runs that must be identical (timings aside)."""
    out = []
    if sorted(a.arrays) != sorted(b.arrays):
        return [f"{what}: array names differ ({sorted(a.arrays)} vs {sorted(b.arrays)})"]
    for key in a.arrays:
        if key.endswith(TIMING_SUFFIX):
            continue
        x, y = a.arrays[key], b.arrays[key]
        if x.shape != y.shape or x.dtype != y.dtype or not np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"):
            out.append(f"{what}: array {key!r} differs")
    if a.events != b.events:
        out.append(f"{what}: events differ")
    if without_timings(a.metadata) != without_timings(b.metadata):
        out.append(f"{what}: metadata differs")
    if dumps_json(without_timings(a.results)) != dumps_json(without_timings(b.results)):
        out.append(f"{what}: results differ")
    return out


def without_timings(mapping: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in mapping.items() if not str(k).endswith(TIMING_SUFFIX)}


def check_summary(trace: Trace, family: Family) -> list[str]:
    """The summary is strict JSON of scalars, led by the core keys with their types."""
    summary = trace.summary()
    out = []
    keys = list(summary)
    if keys[: len(CORE_SUMMARY_KEYS)] != list(CORE_SUMMARY_KEYS):
        out.append(f"summary keys start {keys[: len(CORE_SUMMARY_KEYS)]}, expected {list(CORE_SUMMARY_KEYS)}")
    for key, types in CORE_TYPES.items():
        value = summary.get(key)
        if not isinstance(value, types) or (bool not in types and isinstance(value, bool)):
            out.append(f"summary[{key!r}] is {value!r}, expected {' or '.join(t.__name__ for t in types)}")
    if summary.get("family") != family.name:
        out.append(f"summary['family'] is {summary.get('family')!r}, expected {family.name!r}")
    for key, value in summary.items():
        if value is not None and not isinstance(value, (str, int, float, bool)):
            out.append(f"summary[{key!r}] is a {type(value).__name__}, expected a scalar (sweep rows hold scalars)")
    try:
        json.loads(dumps_json(summary))
    except (TypeError, ValueError) as exc:
        out.append(f"summary is not strict JSON ({exc})")
    undocumented = [k for k in summary if k not in CORE_SUMMARY_KEYS and k not in family.results]
    if undocumented:
        out.append(f"summary keys {undocumented} are not documented in FAMILY.results")
    return out


def check_guarantees(family: Family, spec: SpecModel) -> list[str]:
    report = family.check(spec)
    if not isinstance(report, list) or not all(isinstance(g, Guarantee) for g in report):
        return [f"{family.name}: check(spec) returned {type(report).__name__}, expected a list of Guarantee"]
    return []


def check_round_trip(trace: Trace, directory: Path) -> list[str]:
    trace.save(directory)
    loaded = Trace.load(directory)
    out = compare_traces(trace, loaded, "save/load")
    if dumps_json(trace.summary()) != dumps_json(loaded.summary()):
        out.append("save/load: summary differs")
    return out


def check_figures(trace: Trace, family: Family, directory: Path) -> list[str]:
    module = family.viz_module()
    out = []
    for function, name in (("plot_trace", "plot.png"), ("animate_trace", "animation.gif")):
        draw = getattr(module, function, None)
        if not callable(draw):
            out.append(f"{family.viz} has no {function}(trace, path)")
            continue
        path = directory / name
        draw(trace, path)
        if not path.is_file() or path.stat().st_size == 0:
            out.append(f"{family.viz}.{function} wrote no file")
    return out
