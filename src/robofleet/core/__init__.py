"""Core layer: workspace, geometry kernels, rng, errors, trace and metrics."""

from .errors import ConfigError, InfeasibleError, RobofleetError, ScenarioError, TraceError
from .rng import as_generator, keyed_generator, spawn_seeds
from .trace import Trace
from .workspace import Region, Workspace

__all__ = [
    "ConfigError", "InfeasibleError", "RobofleetError", "ScenarioError", "TraceError",
    "as_generator", "keyed_generator", "spawn_seeds", "Trace", "Region", "Workspace",
]
