"""numba kernels are compiled once per environment (cached on disk), and a compile says so
on the progress line."""

from __future__ import annotations

import importlib
import os
import pkgutil
import subprocess
import sys

import kernel_cache
import numba
import pytest
from numba.core import event
from numba.core.caching import NullCache

import robofleet
from robofleet.core import progress
from robofleet.core.progress import COMPILING, compile_notice, tracked

KERNEL_PACKAGES = ("core", "dynamics", "avoidance", "coordination", "flocking", "search")


def compiled_kernels() -> dict[str, numba.core.registry.CPUDispatcher]:
    """Every numba dispatcher defined at module level in robofleet's algorithm packages."""
    found = {}
    for package in KERNEL_PACKAGES:
        root = importlib.import_module(f"robofleet.{package}")
        for info in pkgutil.walk_packages(root.__path__, f"{root.__name__}."):
            module = importlib.import_module(info.name)
            for name, value in vars(module).items():
                if isinstance(value, numba.core.registry.CPUDispatcher) and value.py_func.__module__ == module.__name__:
                    found[f"{module.__name__}.{name}"] = value
    return found


def test_every_kernel_is_cached_on_disk():
    kernels = compiled_kernels()
    assert len(kernels) > 50  # the walk found the kernels of every family
    uncached = sorted(name for name, kernel in kernels.items() if isinstance(kernel._cache, NullCache))
    assert uncached == [], "njit without cache=True (compiled again by every process)"


COUNT_COMPILES = """
import sys
from numba.core import event
import robofleet
spec = robofleet.load_scenario(sys.argv[1], {sys.argv[2]: 3})
with event.install_recorder("numba:compile") as compiles:
    robofleet.simulate(spec, seed=1)
print(sum(1 for _, e in compiles.buffer if e.is_start))
"""


def compiles_of_a_fresh_process(env: dict) -> int:
    """How many compiles a new process's short ``avoidance/circle_swap`` run starts."""
    budget = robofleet.scenarios.FAMILIES["avoidance"].budget
    result = subprocess.run([sys.executable, "-c", COUNT_COMPILES, "avoidance/circle_swap", budget], env=env,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    return int(result.stdout.split()[-1])


@pytest.mark.slow
def test_a_second_run_in_the_same_environment_compiles_nothing(tmp_path):
    """Fresh processes share a numba cache folder that started empty: the first compiles the
    kernels its run needs, the next loads every one of them from the cache. When the
    suite's warm-up filled the cache from empty (it ran the same short run among the
    shipped scenarios, ``tests/kernel_cache.py``), it was the first process; else the test
    starts both in a new cache folder."""
    recorded = kernel_cache.recorded_first_compiles("avoidance")
    if recorded is not None:
        first, second = sum(recorded.values()), compiles_of_a_fresh_process(dict(os.environ))
    else:
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
        first, second = compiles_of_a_fresh_process(env), compiles_of_a_fresh_process(env)
    assert first > 0 and second == 0, (first, second)


class DescriptionAtCompile(event.Listener):
    """Records what the innermost progress bar says when a compile starts."""

    def __init__(self):
        self.seen = []

    def on_start(self, ev):
        self.seen.append(progress.LIVE_BARS[-1][0].tasks[0].description if progress.LIVE_BARS else None)

    def on_end(self, ev):
        pass


def test_a_compile_is_announced_on_the_progress_line_and_the_line_restored():
    spy = DescriptionAtCompile()
    with compile_notice(True), tracked(3, "circle_swap") as advance:
        with event.install_listener("numba:compile", spy):
            numba.njit(lambda x: x + 1)(1)  # a function never compiled before
        advance()
        after = progress.LIVE_BARS[-1][0].tasks[0].description
    assert spy.seen and spy.seen[0] == f"circle_swap · {COMPILING}"
    assert after == "circle_swap"
    assert progress.LIVE_BARS == []


def test_a_compile_before_the_bar_shows_gets_a_status_line_and_none_without_progress(capsys):
    with compile_notice(True):
        numba.njit(lambda x: x + 2)(1)  # set-up before a loop: the status line (silent off a terminal)
    with compile_notice(False), tracked(2, "quiet", enabled=False):
        numba.njit(lambda x: x + 3)(1)
    captured = capsys.readouterr()
    assert captured.out == "" and "Traceback" not in captured.err
