"""The avoidance family (Zhu et al. 2022, B-UAVC) as the rest of robofleet sees it."""

from ..core.family import Family

FAMILY = Family(
    name="avoidance",
    title="chance-constrained collision avoidance with buffered uncertainty-aware Voronoi cells (B-UAVC)",
    paper="Zhu, Brito & Alonso-Mora 2022",
    spec="robofleet.avoidance.spec:Spec",
    simulate="robofleet.avoidance.simulation:simulate",
    check="robofleet.avoidance.guarantees:check",
    viz="robofleet.viz.avoidance",
    budget="max_steps",
    results="robofleet.avoidance.metrics:RESULTS",
)
