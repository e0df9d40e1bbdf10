"""The avoidance family (Zhu et al. 2022, B-UAVC) as the rest of robofleet sees it."""

from ..core.family import Family
from .guarantees import check
from .metrics import RESULTS
from .simulation import simulate
from .spec import Spec

FAMILY = Family(
    name="avoidance",
    title="chance-constrained collision avoidance with buffered uncertainty-aware Voronoi cells (B-UAVC)",
    paper="Zhu, Brito & Alonso-Mora 2022",
    spec=Spec,
    simulate=simulate,
    check=check,
    viz="robofleet.viz.avoidance",
    budget="max_steps",
    results=RESULTS,
)
