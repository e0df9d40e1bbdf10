"""Suite-wide test settings.

Under CI (``CI=true``) hypothesis runs derandomized, so a green run is reproducible; on a
developer's machine it keeps exploring new examples each run (and remembers failures).
"""

import os
import sys
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
