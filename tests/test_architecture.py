"""The shape of the code: layers, no import circles, the same files in every family; what
importing the package and the quick commands load."""

from __future__ import annotations

import dataclasses
import functools
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import robofleet
from robofleet.core.errors import ConfigError
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


NUMERICAL_LIBRARIES = ("numba", "scipy", "matplotlib", "pandas", "pyarrow")


def modules_loaded_by(code: str) -> list[str]:
    """The numerical libraries a fresh interpreter holds after running ``code``."""
    probe = f"import sys\n{code}\nprint('loaded:', *(m for m in {NUMERICAL_LIBRARIES!r} if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout.splitlines()[-1].split()[1:]


@pytest.mark.parametrize("module", ["robofleet", "robofleet.cli.main"])
def test_importing_the_package_or_its_command_line_loads_no_numerical_library(module):
    assert modules_loaded_by(f"import {module}") == []


@pytest.mark.parametrize("command", [["--version"], ["--help"], ["scenarios"], ["scenarios", "--sweeps"]])
def test_commands_that_answer_at_once_load_no_numerical_library(command):
    code = f"from robofleet.cli.main import main\ntry:\n    main({command!r})\nexcept SystemExit as exc:\n    assert not exc.code, exc.code"
    assert modules_loaded_by(code) == []


@pytest.mark.parametrize("scenario", ["avoidance/circle_swap", "coordination/x_corridor_5_tff", "flocking/wedge_async", "search/fig7"])
def test_validating_a_scenario_loads_no_plotting_or_table_library(scenario):
    code = f"from robofleet.cli.main import main\nmain(['validate', {scenario!r}])\nassert 'scipy.stats' not in sys.modules"
    assert set(modules_loaded_by(code)).isdisjoint({"matplotlib", "pandas", "pyarrow"})


SHIPPED_SCENARIOS = sorted(f"{path.parent.name}/{path.stem}" for path in (Path(__file__).parents[1] / "scenarios").glob("*/*.yaml"))


@functools.cache
def loaded_by_validating(scenario: str) -> tuple[str, ...]:
    """The numerical libraries ``robofleet validate SCENARIO`` loads (one process per scenario)."""
    return tuple(modules_loaded_by(f"from robofleet.cli.main import main\nmain(['validate', {scenario!r}])"))


@pytest.mark.parametrize("scenario", SHIPPED_SCENARIOS)
def test_validating_a_shipped_scenario_loads_no_compiled_kernel_nor_plotting_or_table_library(scenario):
    assert set(loaded_by_validating(scenario)).isdisjoint({"numba", "matplotlib", "pandas", "pyarrow"})


@pytest.mark.parametrize("scenario", SHIPPED_SCENARIOS)
def test_validating_a_shipped_scenario_loads_no_scipy(scenario):
    assert "scipy" not in loaded_by_validating(scenario)


@pytest.mark.parametrize("scenario", ["avoidance/ten_boxes --set method=orca", "coordination/x_corridor_5_tff --set policy.method=btpg",
                                      "coordination/warehouse_50 --set policy.method=optimal"])
def test_validating_another_method_of_a_shipped_scenario_loads_no_numerical_library(scenario):
    name, *overrides = scenario.split()
    assert modules_loaded_by(f"from robofleet.cli.main import main\nmain(['validate', {name!r}, *{overrides!r}])") == []


def test_the_public_names_of_every_package_resolve():
    for package in ("robofleet", "robofleet.core", "robofleet.scenarios", *(f"robofleet.{f}" for f in FAMILY_PACKAGES),
                    "robofleet.experiments"):
        module = importlib.import_module(package)
        for name in module.__all__:
            assert getattr(module, name) is not None, f"{package}.{name}"
            assert name in dir(module)


def test_a_public_name_that_is_also_a_submodule_name_keeps_naming_the_public_object():
    code = ("import robofleet.avoidance.buffer as imported_first\nimport robofleet.avoidance as avoidance\n"
            "assert callable(avoidance.buffer) and avoidance.buffer.__name__ == 'buffer', avoidance.buffer\n"
            "from robofleet.avoidance import buffer\nassert buffer is avoidance.buffer")
    modules_loaded_by(code)


def test_family_fields_given_as_paths_are_imported_on_first_read():
    toy = Family(name="toy", title="t", paper="p", spec="robofleet.search.spec:Spec", simulate="robofleet.search.simulation:simulate",
                 check="robofleet.search.guarantees:check", viz="robofleet.viz.search", budget="max_steps",
                 results="robofleet.search.metrics:RESULTS")
    from robofleet.search.spec import Spec

    assert toy.spec is Spec and toy.results == importlib.import_module("robofleet.search.metrics").RESULTS
    with pytest.raises(ConfigError, match="spec: expected a validated toy scenario"):  # the entry points still check their argument
        toy.simulate(None)
    broken = dataclasses.replace(toy, check="robofleet.search.guarantees:no_such_check")
    with pytest.raises(ConfigError, match=r"family 'toy': check: expected a \"module:attribute\" path that exists, received "):
        broken.check
