"""Suite-wide test settings.

Under CI (``CI=true``) hypothesis runs derandomized, so a green run is reproducible; on a
developer's machine it keeps exploring new examples each run (and remembers failures).
"""

import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest
from hypothesis import settings

from robofleet.scenarios import registry

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
    settings.load_profile("ci")

TOY_DIR = Path(__file__).parent / "experiments"


@pytest.fixture
def toy_family(monkeypatch):
    """Register the toy scenario family (this process, and forked workers, only)."""
    monkeypatch.syspath_prepend(str(TOY_DIR))
    import experiments_toy_family

    monkeypatch.setitem(registry.FAMILIES, "toy", experiments_toy_family.FAMILY)
    return "toy"


@pytest.fixture(scope="session")
def robofleet_bin() -> Path:
    """The installed ``robofleet`` console script next to this interpreter."""
    path = Path(sys.executable).parent / "robofleet"
    if not path.exists():
        pytest.fail(f"console script not installed at {path}")
    return path


EXTENDED = (
    # whole runs, sweeps, reproductions, processes, builds, the browser
    "conformance/", "fuzz/", "ros2/", "viz/", "experiments/", "envs/", "test_wheel.py", "test_docs.py", "test_examples.py",
    "test_benchmarks_smoke.py", "test_readme.py", "test_docs_snippets.py", "cli/test_memory_budget.py",
    "cli/test_run_interrupted.py", "avoidance/test_reproduce.py", "coordination/test_reproduce.py",
    "flocking/test_reproduce.py", "search/test_reproduce.py", "flocking/test_family.py", "coordination/test_family.py",
    "avoidance/test_viz.py",
    # long randomized searches and closed loops of the algorithms
    "avoidance/test_braking_adversarial.py", "avoidance/test_braking.py", "avoidance/test_cell3d.py",
    "avoidance/test_cell_kernels.py", "avoidance/test_detour.py", "avoidance/test_liveness.py",
    "avoidance/test_models_scenarios.py", "avoidance/test_mpc.py", "avoidance/test_mpc_rti.py",
    "avoidance/test_navigation.py", "avoidance/test_orca.py", "avoidance/test_premise.py",
    "coordination/test_theorems.py", "coordination/test_supervisor_threads.py", "flocking/test_axis_slot.py",
    "flocking/test_variants.py",
    "coordination/test_peers.py", "coordination/test_compiled.py", "search/test_baselines.py", "cli/test_damaged_traces.py",
)
"""Tests (folders and files below tests/) left out of ``make check``, marked ``extended``:
``make test`` runs them."""


SHARED_SCOPES = ("class", "module", "package")
"""Fixture scopes whose value the tests of one file (or folder) share."""


def shared_fixture_home(item) -> str | None:
    """Where a shared fixture ``item`` asks for is defined (its file or folder), or ``None``
    when it uses none: the tests sharing such a fixture (a simulated run, a Dask cluster, a
    built wheel, ...) run on one worker, which builds it once. Fixtures every test of a
    file gets without asking (``autouse``: settings of the environment) do not count."""
    homes = sorted(
        definitions[-1].baseid
        for definitions in item._fixtureinfo.name2fixturedefs.values()
        if definitions and definitions[-1].scope in SHARED_SCOPES and not getattr(definitions[-1], "_autouse", False)
    )
    return homes[0] if homes else None


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Mark the :data:`EXTENDED` tests; keep the tests that share a file's fixture on one
    worker (``xdist_group``, for ``--dist loadgroup``); put the long tests first, the
    ``slow`` ones, then the ``extended`` ones: with ``--dist loadgroup
    --no-loadscope-reorder`` (the Makefile) each worker takes the next test when it is
    free, so the longest start at once and the short ones fill the end, instead of the
    run ending on one worker still busy with a long test."""
    tests = Path(__file__).parent
    for item in items:
        where = item.path.relative_to(tests).as_posix() if item.path.is_relative_to(tests) else ""
        if where.startswith(EXTENDED):
            item.add_marker(pytest.mark.extended)
        home = shared_fixture_home(item)
        if home is not None:
            item.add_marker(pytest.mark.xdist_group(home))
    items.sort(key=lambda item: (item.get_closest_marker("slow") is None, item.get_closest_marker("extended") is None))


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session):
    """With test workers (``-n``), fill numba's cache before they start, when it is empty
    (:mod:`kernel_cache`): each kernel is then compiled once, not once per worker. The
    workers, started after this hook, inherit ``kernel_cache.FIRST_COMPILES``."""
    if session.config.pluginmanager.has_plugin("dsession"):
        import kernel_cache

        record = Path(tempfile.mkdtemp(prefix="robofleet-first-compiles-"))
        session.config.add_cleanup(lambda: shutil.rmtree(record, ignore_errors=True))
        if kernel_cache.warm_up(record):
            os.environ[kernel_cache.FIRST_COMPILES] = str(record)
