"""robofleet: decentralized multi-robot coordination.

Public entry points: :func:`load_scenario`, :func:`simulate` and the :class:`Trace` they
produce; one package per paper (:mod:`robofleet.avoidance`, :mod:`robofleet.coordination`,
:mod:`robofleet.flocking`, :mod:`robofleet.search`).
"""

from .core.errors import RobofleetError, ScenarioError
from .core.lazy import exports
from .scenarios import load_scenario, simulate

__version__ = "0.1.0"
__all__ = ["load_scenario", "simulate", "Trace", "Workspace", "RobofleetError", "ScenarioError", "__version__"]
__getattr__, __dir__ = exports(__name__, {".core.trace": ["Trace"], ".core.workspace": ["Workspace"]})
