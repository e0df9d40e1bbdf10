"""Core layer: workspace, geometry kernels, rng, errors, trace and metrics."""

from .errors import ConfigError, InfeasibleError, RobofleetError, ScenarioError, TraceError
from .lazy import exports

__all__ = [
    "ConfigError", "InfeasibleError", "RobofleetError", "ScenarioError", "TraceError",
    "as_generator", "keyed_generator", "spawn_seeds", "Trace", "Region", "Workspace",
]
__getattr__, __dir__ = exports(__name__, {
    ".rng": ["as_generator", "keyed_generator", "spawn_seeds"],
    ".trace": ["Trace"],
    ".workspace": ["Region", "Workspace"],
})
