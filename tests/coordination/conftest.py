import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture
def fast_thread_switches():
    """The interpreter switches threads every 10 µs (instead of 5 ms) during the test, so
    threaded tests interleave the robots' calls far more finely."""
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)
    yield
    sys.setswitchinterval(interval)
