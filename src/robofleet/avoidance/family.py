"""TEMPORARY wiring of the avoidance family into the family table (replaced by the redesign)."""

from ..core.family import Family
from . import scenario

FAMILY = Family(name="avoidance", title="avoidance", paper="", spec=scenario.Spec, simulate=scenario.simulate,
                check=lambda spec: [], viz="robofleet.viz.avoidance", budget="max_steps")
