"""The coordination family as the rest of robofleet sees it (:data:`FAMILY`)."""

from __future__ import annotations

from ..core.family import Family
from .guarantees import check
from .metrics import RESULTS
from .simulation import simulate
from .spec import Spec

PAPER = "a graph-based theory of deadlock for label flipping (anonymous, 2021), on RMTRACK (Čáp, Gregoire & Frazzoli 2016)"

FAMILY = Family(
    name="coordination",
    title="deadlock-free execution of multi-robot plans under disturbances (RMTRACK, TFF/TFA flips, segment graphs)",
    paper=PAPER,
    spec=Spec,
    simulate=simulate,
    check=check,
    viz="robofleet.viz.coordination",
    budget="simulation.max_steps",
    results=RESULTS,
)
