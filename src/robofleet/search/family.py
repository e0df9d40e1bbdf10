"""The search family (Yang 2017) as the rest of robofleet sees it: :data:`FAMILY`."""

from ..core.family import Family
from .guarantees import check
from .metrics import RESULTS
from .simulation import simulate
from .spec import Spec

FAMILY = Family(
    name="search",
    title="decentralized collision-free search of an unknown area on a grid",
    paper="Yang 2017 (CCC)",
    spec=Spec,
    simulate=simulate,
    check=check,
    viz="robofleet.viz.search",
    budget="max_steps",
    results=RESULTS,
)
