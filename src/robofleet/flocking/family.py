"""TEMPORARY wiring of the flocking family into the family table (replaced by the redesign)."""

from ..core.family import Family
from . import scenario

FAMILY = Family(name="flocking", title="flocking", paper="", spec=scenario.Spec, simulate=scenario.simulate,
                check=lambda spec: [], viz="robofleet.viz.flocking", budget="max_steps")
