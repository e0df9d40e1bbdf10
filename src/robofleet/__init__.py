"""robofleet: decentralized multi-robot coordination.

Public entry points: :func:`load_scenario`, :func:`simulate` and the :class:`Trace` they
produce; one package per paper (:mod:`robofleet.avoidance`, :mod:`robofleet.coordination`,
:mod:`robofleet.flocking`, :mod:`robofleet.search`).
"""

from .core import RobofleetError, ScenarioError, Trace, Workspace
from .scenarios import load_scenario, simulate

__version__ = "0.1.0"
__all__ = ["load_scenario", "simulate", "Trace", "Workspace", "RobofleetError", "ScenarioError", "__version__"]
