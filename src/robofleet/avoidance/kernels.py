"""Threads of the compiled avoidance kernels (cells, projection, ORCA, neighbour search).

The kernels run robots in parallel with ``numba.prange`` when a fleet has at least
:data:`PARALLEL_MIN_ROBOTS` robots (below that, starting the threads costs more than it
saves), numba has more than one thread, and the call comes from the main thread (worker
threads of an executor, which already run tasks side by side, get the serial kernels).
Every robot's result is computed by one thread from shared read-only inputs — no
reductions across robots — so the results are bit-identical whatever the number of
threads (``tests/avoidance/test_cell_kernels.py`` checks it).

Threads: numba's, all cores by default; ``NUMBA_NUM_THREADS=1`` in the environment (read
when numba starts) or :func:`set_threads` at run time. Threading layer: numba's
``workqueue`` unless ``NUMBA_THREADING_LAYER`` says otherwise: on a loaded 2-core
machine the OpenMP layer made two threads 1.5–4× slower than one (its barrier waits for
a descheduled worker), with the workqueue layer two threads ran ×0.7–1.2 the speed of
one (``benchmarks/vs_rvo2.py --threads 1 2``); GNU OpenMP is also not safe across
``fork``, which the process executor uses.
"""

from __future__ import annotations

import os
import threading

import numba

from ..core.errors import ConfigError

PARALLEL_MIN_ROBOTS = 4096
"""Fleets smaller than this run the kernels on the calling thread only."""

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"


def use_parallel(n: int) -> bool:
    """Whether a kernel over ``n`` robots should run on numba's threads."""
    return n >= PARALLEL_MIN_ROBOTS and numba.get_num_threads() > 1 and threading.current_thread() is threading.main_thread()


def set_threads(threads: int) -> None:
    """Run the avoidance kernels on ``threads`` threads (1 … ``NUMBA_NUM_THREADS``) from now on."""
    limit = numba.config.NUMBA_NUM_THREADS
    if isinstance(threads, bool) or not isinstance(threads, int) or not 1 <= threads <= limit:
        raise ConfigError(f"threads: expected an integer in [1, {limit}] (NUMBA_NUM_THREADS), received {threads!r}")
    numba.set_num_threads(threads)


def get_threads() -> int:
    """The number of threads the kernels use now."""
    return numba.get_num_threads()
