"""Fixtures of the experiment-machinery tests."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from robofleet.scenarios import registry

HERE = Path(__file__).parent


@pytest.fixture
def toy_family(monkeypatch):
    """Register the toy scenario family (this process, and forked workers, only)."""
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(registry.FAMILIES, "toy", "experiments_toy_family")
    return "toy"


@pytest.fixture(scope="session")
def robofleet_bin() -> Path:
    """The installed ``robofleet`` console script next to this interpreter."""
    path = Path(sys.executable).parent / "robofleet"
    if not path.exists():
        pytest.fail(f"console script not installed at {path}")
    return path
