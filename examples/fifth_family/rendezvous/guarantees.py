"""The checkable conditions of the theory, evaluated on a scenario (what `robofleet check` prints)."""

from __future__ import annotations

import math

from robofleet.core.family import Guarantee

from .spec import Spec


def check(spec: Spec) -> list[Guarantee]:
    """Hull invariance (always, from the weights) and connectivity (when the range covers the start square)."""
    robots = spec.robots
    complete = robots.sensing_range >= robots.area * math.sqrt(2)
    return [
        Guarantee("convex hull never grows", "consensus step, weights g/(1 + d_i)", holds=0 < robots.gain <= 1,
                  detail=f"g = {robots.gain}", consequence="no robot ever leaves the hull of the starts"),
        Guarantee("sensing graph complete at every step", "range ≥ diagonal of the start square", holds=complete,
                  detail=f"range {robots.sensing_range:g} m against a diagonal of {robots.area * math.sqrt(2):.3g} m: "
                         "robots may lose each other and gather in several groups",
                  consequence="the fleet gathers at one point, geometrically fast"),
    ]
