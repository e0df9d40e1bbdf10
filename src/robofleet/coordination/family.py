"""The coordination family as the rest of robofleet sees it (:data:`FAMILY`)."""

from __future__ import annotations

from ..core.family import Family

PAPER = "a graph-based theory of deadlock for label flipping (anonymous, 2021), on RMTRACK (Čáp, Gregoire & Frazzoli 2016)"

FAMILY = Family(
    name="coordination",
    title="deadlock-free execution of multi-robot plans under disturbances (RMTRACK, TFF/TFA flips, segment graphs)",
    paper=PAPER,
    spec="robofleet.coordination.spec:Spec",
    simulate="robofleet.coordination.simulation:simulate",
    check="robofleet.coordination.guarantees:check",
    viz="robofleet.viz.coordination",
    budget="simulation.max_steps",
    results="robofleet.coordination.metrics:RESULTS",
)
