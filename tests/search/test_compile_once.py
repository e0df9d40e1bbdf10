"""A first search run in an empty numba cache compiles each robofleet kernel once.

When the suite's warm-up started from an empty cache (a fresh clone, as in CI), it recorded
what every shipped search scenario compiled (``tests/kernel_cache.py``), and that record is
checked; otherwise the test compiles the search kernels itself, in an empty cache."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import kernel_cache
import pytest

COMPILES_PER_KERNEL = """
import collections
from numba.core import event
import robofleet
spec = robofleet.load_scenario("search/fig7")
with event.install_recorder("numba:compile") as compiles:
    robofleet.simulate(spec, seed=1)
count = collections.Counter()
for _, e in compiles.buffer:
    func = e.data["dispatcher"].py_func
    if e.is_start and func.__module__.startswith("robofleet."):
        count[f"{func.__module__}.{func.__qualname__}"] += 1
for name, n in sorted(count.items()):
    print(name, n)
"""


def first_search_compiles(tmp_path: Path) -> dict[str, int]:
    """How often each robofleet kernel was compiled by first search runs in an empty cache:
    the warm-up's record of every shipped search scenario when there is one, else a run of
    ``search/fig7`` in the empty cache ``tmp_path``."""
    recorded = kernel_cache.recorded_first_compiles("search")
    if recorded is not None:
        return recorded
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    result = subprocess.run([sys.executable, "-c", COMPILES_PER_KERNEL], env=env, capture_output=True, text=True,
                            timeout=900)
    assert result.returncode == 0, result.stderr[-2000:]
    return {name: int(n) for name, n in (line.split() for line in result.stdout.splitlines())}


@pytest.mark.slow
def test_a_first_search_run_compiles_each_kernel_once(tmp_path):
    """Every call site passes one set of argument types (no literal constants, one layout),
    so no kernel of the search loop is compiled for a second signature."""
    counts = first_search_compiles(tmp_path)
    assert "robofleet.search.loop_kernels.run_steps" in counts
    assert {name: n for name, n in counts.items() if n > 1} == {}
