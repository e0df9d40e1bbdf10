"""TEMPORARY wiring of the search family into the family table (replaced by the redesign)."""

from ..core.family import Family
from . import scenario

FAMILY = Family(name="search", title="search", paper="", spec=scenario.Spec, simulate=scenario.simulate,
                check=lambda spec: [], viz="robofleet.viz.search", budget="max_steps")
