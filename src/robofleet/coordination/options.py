"""The options of a coordination run that a scenario file chooses: the execution method
and its flip-test estimate (:mod:`.plan_execution`), the segment graph's resolution
(:mod:`.segment_graph`), the ``optimal`` method's search settings (:mod:`.optimal`) and the
offline searches' visit budget (:mod:`.btpg`). Parameters only, so a scenario file is
read without loading the compiled kernels of those modules, which re-export these names.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Method(str, Enum):
    """Execution policy: plain RMTRACK, RMTRACK with a flip test, BTPG (first come on the
    offline-classified switchable obstacles) or the optimal orders within a horizon."""

    RMTRACK = "rmtrack"
    TFF = "tff"
    TFA = "tfa"
    BTPG = "btpg"
    OPTIMAL = "optimal"


class Estimate(str, Enum):
    """Where the flip tests' disturbance probabilities come from."""

    KNOWN = "known"
    LEARNED = "learned"


class Resolution(str, Enum):
    """How finely obstacle-label edges follow an obstacle's shape."""

    EXACT = "exact"
    DEFINITION3 = "definition3"


@dataclass(frozen=True)
class OptimalSettings:
    """How far ahead and how hard the ``optimal`` method searches.

    Attributes
    ----------
    horizon:
        plan steps: an obstacle is decided when one of its robots is at most this far from it.
    max_open:
        at most this many obstacles are decided at once, those whose robots are due first
        (the others keep their labels until a later decision).
    node_budget:
        best-first expansions per decision.
    period:
        steps between the periodic decisions (a robot stopped at an obstacle that may be
        relabelled also calls one at once).
    """

    horizon: int = 50
    max_open: int = 200
    node_budget: int = 4
    period: int = 20


DEFAULT_VISIT_BUDGET = 100_000_000
"""Vertices the offline searches may visit in all (a few seconds of compiled search; the
200-robot warehouse instances need about half of it)."""
