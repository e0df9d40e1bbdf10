"""The search family (Yang 2017) as the rest of robofleet sees it: :data:`FAMILY`."""

from ..core.family import Family

FAMILY = Family(
    name="search",
    title="decentralized collision-free search of an unknown area on a grid",
    paper="Yang 2017 (CCC)",
    spec="robofleet.search.spec:Spec",
    simulate="robofleet.search.simulation:simulate",
    check="robofleet.search.guarantees:check",
    viz="robofleet.viz.search",
    budget="max_steps",
    results="robofleet.search.metrics:RESULTS",
)
