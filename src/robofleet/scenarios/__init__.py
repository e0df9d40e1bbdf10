"""Scenarios: the family table, loading and validation, and the shipped catalogue.

``robofleet.scenarios.list()`` lists the shipped scenarios, ``robofleet.scenarios.path(name)``
gives one's file; :func:`load_scenario` and :func:`simulate` accept those names too.
"""

from __future__ import annotations

import builtins
from pathlib import Path

from ..core import catalogue
from ..core.catalogue import Entry, names, resolve
from ..core.catalogue import list as _catalogue_list
from ..core.catalogue import path as _catalogue_path
from ..core.lazy import exports
from .registry import FAMILIES, family, family_of, load_scenario, simulate


def list(kind: str = "scenarios") -> builtins.list[Entry]:  # noqa: A001 - public name of the catalogue
    """Every shipped scenario (``kind="sweeps"``: sweep) as :class:`Entry` (name, family, description, path)."""
    return _catalogue_list(kind)


def path(name: str, kind: str = "scenarios") -> Path:
    """The file of the shipped scenario (or sweep) ``name``, e.g. ``"avoidance/circle_swap"``."""
    return _catalogue_path(name, kind)


__all__ = ["catalogue", "Entry", "FAMILIES", "DEFAULT_FAMILY", "family", "family_of", "list", "path", "names", "resolve",
           "load_scenario", "read_scenario", "simulate"]
__getattr__, __dir__ = exports(__name__, {"robofleet.core.config": ["DEFAULT_FAMILY", "read_scenario"]})
