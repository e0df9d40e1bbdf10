"""Scenario files: strict validation and the family registry."""

from .base import SpecModel, read_mapping, set_path, validate_model
from .registry import FAMILIES, load_scenario, simulate
from .shipped import shipped_scenario

__all__ = ["SpecModel", "read_mapping", "set_path", "validate_model", "FAMILIES", "load_scenario", "simulate", "shipped_scenario"]
