"""Fill numba's on-disk cache before the test workers start, when it is empty.

Each robofleet kernel is compiled once per environment and cached on disk (``cache=True``;
``tests/test_compiled_kernels.py``). With an empty cache — a fresh clone, as in CI — the
two test workers would each compile the same kernels at the same time, in their first
tests. Instead the controller runs a few steps of every shipped scenario first, in two
processes side by side (one per worker, the families split by compile time), and the
workers load what those compiled. Run as a script it warms the families it is given:
``python tests/kernel_cache.py avoidance flocking``; with ``--record FOLDER`` it also writes,
per family, how often each robofleet kernel was compiled during that family's runs
(``FOLDER/<family>.json``): from an empty cache, that is what a first run in a fresh
environment compiles, which ``tests/search/test_compile_once.py`` reads instead of compiling
the search kernels a second time.
"""

from __future__ import annotations

import collections
import json
import os
import re
import subprocess
import sys
from pathlib import Path

SOURCES = Path(__file__).resolve().parents[1] / "src" / "robofleet"

SHORT_RUNS = {"avoidance": {"max_steps": 3}, "coordination": {"simulation.max_steps": 30}, "flocking": {"duration": 3},
              "search": {}}
"""Overrides that cut every shipped scenario of a family to a few steps: enough to call
every kernel its run calls, with the argument types of a full run."""

VARIANTS = {"avoidance/ten_boxes": [{"method": method} for method in ("bvc", "orca")],
            "coordination/x_corridor_5_tff": [{"policy.method": method, "simulation.max_steps": 400}
                                              for method in ("rmtrack", "tfa", "btpg", "optimal")]}
"""Further runs of a scenario, for the kernels of the methods its file does not use."""

WARM_UP_GROUPS = (("avoidance", "flocking"), ("coordination", "search"))
"""Families per warm-up process, split so that both compile for about as long."""


CACHED_KERNEL = re.compile(r"^@numba\.njit\((?![^)]*inline=.always.)", re.MULTILINE)
"""A kernel of its own in the cache (``inline="always"`` ones are compiled into their callers)."""


def kernel_sources() -> list[Path]:
    """The robofleet modules that define kernels cached on their own."""
    return [path for path in SOURCES.rglob("*.py") if CACHED_KERNEL.search(path.read_text(encoding="utf-8"))]


def cache_directory(source: Path) -> Path:
    """Where numba caches the kernels of ``source`` (its ``__pycache__``, or the folder
    numba derives from ``NUMBA_CACHE_DIR``)."""
    from numba.core import caching, config

    if config.CACHE_DIR:
        return Path(config.CACHE_DIR) / caching.UserProvidedCacheLocator.get_suitable_cache_subpath(str(source))
    return source.parent / "__pycache__"


def is_warm() -> bool:
    """Whether every kernel module has a cache index at least as new as its source (a
    stale or missing index means its kernels would be compiled by the next run)."""
    for source in kernel_sources():
        written = [index.stat().st_mtime for index in cache_directory(source).glob(f"{source.stem}.*.nbi")]
        if not written or max(written) < source.stat().st_mtime:
            return False
    return True


FIRST_COMPILES = "ROBOFLEET_TEST_FIRST_COMPILES"
"""Environment variable naming the folder where the warm-up recorded, per family, the
kernels a first run in an empty cache compiled (set by ``tests/conftest.py`` only when the
cache was empty)."""


def recorded_first_compiles(family: str) -> dict[str, int] | None:
    """What the warm-up's first runs of ``family`` compiled in the empty cache (kernel →
    compiles), or ``None`` when this session's warm-up did not start from an empty cache."""
    folder = os.environ.get(FIRST_COMPILES)
    record = Path(folder) / f"{family}.json" if folder else None
    return json.loads(record.read_text(encoding="utf-8")) if record is not None and record.is_file() else None


def is_empty() -> bool:
    """Whether no kernel module has a cache index yet (a fresh environment)."""
    return not any(any(cache_directory(source).glob(f"{source.stem}.*.nbi")) for source in kernel_sources())


def warm_up(record: Path) -> bool:
    """Compile into the cache in :data:`WARM_UP_GROUPS` processes side by side, unless it
    is warm already. A scenario that fails to run is left to the tests to report. When the
    cache was empty, the compile counts of every family are written to ``record``
    (:func:`run_families`) and ``True`` is returned."""
    if os.environ.get("NUMBA_DISABLE_JIT") == "1" or is_warm():
        return False
    fresh = is_empty()
    options = ["--record", str(record)] if fresh else []
    env = {**os.environ, "MPLBACKEND": "Agg"}
    processes = [subprocess.Popen([sys.executable, __file__, *options, *families], env=env, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL) for families in WARM_UP_GROUPS]
    for process in processes:
        process.wait()
    return fresh


def run_families(families: list[str], record: Path | None = None) -> None:
    """A few steps of every shipped scenario of ``families`` (and its :data:`VARIANTS`), seed
    1, a family at a time; with ``record``, how often each robofleet kernel was compiled
    during a family's runs goes to ``record/<family>.json``."""
    from numba.core import event

    import robofleet
    from robofleet.scenarios import catalogue

    for family in families:
        with event.install_recorder("numba:compile") as compiles:
            for name in (name for name in catalogue.names() if name.split("/")[0] == family):
                for overrides in [{}, *VARIANTS.get(name, [])]:
                    try:
                        robofleet.simulate(robofleet.load_scenario(name, {**SHORT_RUNS[family], **overrides}), seed=1)
                    except Exception:  # noqa: BLE001 - the tests of that scenario report it
                        continue
        if record is not None:
            write_counts(record / f"{family}.json", compile_counts(compiles.buffer))


def compile_counts(buffer) -> dict[str, int]:
    """How often each robofleet kernel was compiled, from numba's recorded compile events."""
    count = collections.Counter()
    for _, compile_event in buffer:
        function = compile_event.data["dispatcher"].py_func
        if compile_event.is_start and function.__module__.startswith("robofleet."):
            count[f"{function.__module__}.{function.__qualname__}"] += 1
    return dict(sorted(count.items()))


def write_counts(path: Path, counts: dict[str, int]) -> None:
    """``counts`` as JSON at ``path``, written whole (a temporary file renamed)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(".partial")
    partial.write_text(json.dumps(counts, indent=1), encoding="utf-8")
    partial.replace(path)


if __name__ == "__main__":
    arguments = sys.argv[1:]
    if arguments[:1] == ["--record"]:
        run_families(arguments[2:], Path(arguments[1]))
    else:
        run_families(arguments)
