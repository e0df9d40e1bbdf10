"""The family contract: what every paper's package gives the rest of robofleet.

Each family package has the same files (``spec.py``, ``simulation.py``, ``metrics.py``,
``guarantees.py``, ``family.py`` and one file per paper-named algorithm); its
``family.py`` holds one :class:`Family` value, ``FAMILY``. The table of all of them
(:data:`robofleet.scenarios.FAMILIES`) is the only registry: loading, the CLI, viz and the
conformance suite read it, in the spirit of Gymnasium's registration table.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any, Callable, Mapping, Protocol

from .config import SpecModel
from .errors import ConfigError
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


class SimulateFunction(Protocol):
    def __call__(self, spec: Any, seed: int | None = None, progress: bool = False) -> Trace: ...


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
    """

    name: str
    title: str
    paper: str
    spec: type[SpecModel]
    simulate: SimulateFunction
    check: Callable[[Any], list[Guarantee]]
    viz: str
    budget: str
    results: Mapping[str, str] = field(default_factory=dict)

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
