"""The flocking family as the rest of robofleet sees it (Gervasi & Prencipe 2001: Gervasi & Prencipe,
*Flocking by a set of autonomous mobile robots*, Univ. of Pisa TR-01-24, 2001)."""

from __future__ import annotations

from ..core.family import Family

FAMILY = Family(
    name="flocking",
    title="leader-following flocking of oblivious, anonymous, asynchronous robots (Look-Compute-Move)",
    paper="Gervasi & Prencipe 2001",
    spec="robofleet.flocking.spec:Spec",
    simulate="robofleet.flocking.simulation:simulate",
    check="robofleet.flocking.guarantees:check",
    viz="robofleet.viz.flocking",
    budget="duration",
    results="robofleet.flocking.metrics:RESULTS",
)
