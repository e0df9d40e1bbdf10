"""The family contract: what every paper's package gives the rest of robofleet.

Each family package has the same files (``spec.py``, ``simulation.py``, ``metrics.py``,
``guarantees.py``, ``family.py`` and one file per paper-named algorithm); its
``family.py`` holds one :class:`Family` value, ``FAMILY``. The table of all of them
(:data:`robofleet.scenarios.FAMILIES`) is the only registry: loading, the CLI, viz and the
conformance suite read it, in the spirit of Gymnasium's registration table.
"""

from __future__ import annotations

import functools
import importlib
from dataclasses import dataclass, field
from types import ModuleType
from typing import TYPE_CHECKING, Any, Callable, Mapping, Protocol

from .errors import ConfigError

if TYPE_CHECKING:
    from .config import SpecModel
    from .trace import Trace


@dataclass(frozen=True)
class Guarantee:
    """One checkable condition of a paper, evaluated on one scenario.

    Attributes
    ----------
    name: what is checked, in the paper's words ("non-conflicting trajectories").
    reference: where the paper states it ("Definition 4", "Theorem 4").
    holds: whether the condition holds for this scenario.
    detail: one line of evidence (counts, the first violation...).
    consequence: what follows when it holds ("deadlock ⇔ cycle in the segment graph").
    """

    name: str
    reference: str
    holds: bool
    detail: str = ""
    consequence: str = ""

    def line(self) -> str:
        """One line for the terminal: ``name (reference): yes — consequence / detail``."""
        verdict = "yes" if self.holds else "no"
        tail = self.consequence if self.holds and self.consequence else self.detail
        return f"{self.name} ({self.reference}): {verdict}" + (f" — {tail}" if tail else "")


def expect_spec(spec: Any, model: type[SpecModel], family: str) -> None:
    """Refuse anything but a validated ``model`` (one line naming what was received)."""
    if not isinstance(spec, model):
        raise ConfigError(f"spec: expected a validated {family} scenario (a {model.__module__}.{model.__name__}, "
                          f"as robofleet.load_scenario returns), received {type(spec).__name__}")


def spec_checked(function: Callable, model: type[SpecModel], family: str) -> Callable:
    """``function(spec, ...)`` that first checks ``spec`` with :func:`expect_spec` (applied once)."""
    if getattr(function, "__robofleet_checked__", None) is model:
        return function

    @functools.wraps(function)
    def checked(spec: Any, *args: Any, **kwargs: Any) -> Any:
        expect_spec(spec, model, family)
        return function(spec, *args, **kwargs)

    checked.__robofleet_checked__ = model  # type: ignore[attr-defined]
    return checked


class SimulateFunction(Protocol):
    def __call__(self, spec: Any, seed: int | None = None, progress: bool = False) -> Trace: ...


IMPORTED_ON_USE = ("spec", "simulate", "check", "results")
"""The fields of a :class:`Family` that may name their value as ``"module:attribute"``."""


@dataclass(frozen=True)
class Family:
    """One paper's system, as the rest of robofleet sees it.

    Attributes
    ----------
    name: the ``family:`` key of its scenario files and the package name.
    title: one line ("chance-constrained collision avoidance (B-UAVC)").
    paper: the paper by author and year ("Zhu, Brito & Alonso-Mora 2022").
    spec: the frozen, validated scenario model (a :class:`SpecModel`).
    simulate: ``simulate(spec, seed=None, progress=False) -> Trace`` under the seed rule
        of :mod:`robofleet.core.rng`.
    check: ``check(spec) -> list[Guarantee]``, the paper's checkable conditions.
    viz: module path of its figures (``plot_trace(trace, path)``, ``animate_trace(trace, path)``),
        imported only when a figure is drawn.
    budget: dotted path of the spec's step budget (``max_steps``), which the conformance
        suite shortens to run every shipped scenario at a tiny budget.
    results: the family's own summary keys (beyond the core ones) and their meaning.

    ``spec``, ``simulate``, ``check`` and ``results`` may be given as the object or as its
    ``"module:attribute"`` path, imported when the attribute is first read (as ``viz`` is
    when a figure is drawn): the family table then imports no algorithm, so the command
    line answers ``--help`` at once and validating a scenario loads its own family's
    model only. Reading the attribute gives the object either way.
    """

    name: str
    title: str
    paper: str
    spec: type[SpecModel] | str
    simulate: SimulateFunction | str
    check: Callable[[Any], list[Guarantee]] | str
    viz: str
    budget: str
    results: Mapping[str, str] | str = field(default_factory=dict)

    def __post_init__(self) -> None:
        # the four fields are resolved by __getattr__ on first read: kept aside until then
        given = {name: self.__dict__.pop(name) for name in IMPORTED_ON_USE}
        object.__setattr__(self, "_given", given)

    def __getattr__(self, name: str) -> Any:
        given = self.__dict__.get("_given")
        if given is None or name not in given:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        value = given[name]
        if isinstance(value, str):
            value = self.imported(name, value)
        if name in ("simulate", "check"):
            # the entry points refuse anything but this family's spec in one line, before running
            value = spec_checked(value, self.spec, self.name)
        object.__setattr__(self, name, value)
        return value

    def imported(self, field_name: str, path: str) -> Any:
        """The object a ``"module:attribute"`` path names (one-line error if it names none)."""
        module_name, _, attribute = path.partition(":")
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name is None or not module_name.startswith(exc.name):
                raise  # the module exists but needs one that is missing
            module = None
        if not attribute or not hasattr(module, attribute):
            raise ConfigError(f"family {self.name!r}: {field_name}: expected a \"module:attribute\" path that exists, "
                              f"received {path!r}")
        return getattr(module, attribute)

    def viz_module(self) -> ModuleType:
        """The figures module (imported now; matplotlib is loaded only here).

        Raises
        ------
        ConfigError
            If the family names a figures module that does not exist.
        """
        try:
            return importlib.import_module(self.viz)
        except ModuleNotFoundError as exc:
            if exc.name is None or not self.viz.startswith(exc.name):
                raise
            raise ConfigError(f"family {self.name!r}: viz: expected a figures module, received {self.viz!r}, which does not exist") from None
