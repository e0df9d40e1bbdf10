"""The shape of the code: layers, no import circles, the same files in every family."""

from __future__ import annotations

from pathlib import Path

import robofleet
from robofleet.core.family import Family
from robofleet.scenarios import FAMILIES
from robofleet.testing.layers import FAMILY_PACKAGES, read_graph

CONTRACT_FILES = ("spec.py", "simulation.py", "metrics.py", "guarantees.py", "family.py")
PACKAGE_DIR = Path(robofleet.__file__).parent


def test_no_import_circles():
    assert read_graph().cycles() == []


def test_nothing_imports_upward_or_across_families():
    assert read_graph().violations() == []


def test_every_family_package_has_the_contract_files_and_is_in_the_table():
    assert set(FAMILIES) == set(FAMILY_PACKAGES)
    for name in FAMILY_PACKAGES:
        present = {p.name for p in (PACKAGE_DIR / name).glob("*.py")}
        assert set(CONTRACT_FILES) <= present, f"{name} lacks {sorted(set(CONTRACT_FILES) - present)}"
        family = FAMILIES[name]
        assert isinstance(family, Family) and family.name == name
        assert family.simulate.__module__ == f"robofleet.{name}.simulation"
        assert family.check.__module__ == f"robofleet.{name}.guarantees"
        assert family.spec.__module__ == f"robofleet.{name}.spec"
        assert family.viz == f"robofleet.viz.{name}"


def test_the_package_is_typed():
    assert (PACKAGE_DIR / "py.typed").is_file()
