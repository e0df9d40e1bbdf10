"""TEMPORARY wiring of the coordination family into the family table (replaced by the redesign)."""

from ..core.family import Family
from . import scenario

FAMILY = Family(name="coordination", title="coordination", paper="", spec=scenario.Spec, simulate=scenario.simulate,
                check=lambda spec: [], viz="robofleet.viz.coordination", budget="max_steps")
