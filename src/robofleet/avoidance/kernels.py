"""Threads of the compiled avoidance kernels (cells, projection, ORCA, neighbour search),
products of many short rows kept off OpenBLAS's threads (:func:`row_products`), and the
per-thread buffers that large per-step arrays reuse (:func:`work_array`,
:func:`reused_array`, of any size within :func:`run_buffers`).

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
import sys
import threading
from contextlib import contextmanager
from math import prod
from typing import Iterator

import numba
import numpy as np

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


BLAS_BLOCK = 8192
"""Rows per block of :func:`row_products`: OpenBLAS runs a product ``(rows × k)(k × m)``
on the calling thread when ``rows · k · m < 262,144`` (at most ``2 · BLAS_BLOCK`` rows of
``k, m ≤ 3`` here)."""


def row_products(x: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``x @ matrix`` for many short rows ``(N, k)`` by a small ``(k, m)`` matrix, bit for
    bit, in blocks of :data:`BLAS_BLOCK` rows (the last block takes the remainder, so every
    block has at least that many rows and each row is rounded as in the single product).
    OpenBLAS splits one product over ``N ≥ 65,536`` rows across its threads, which on 2 cores
    shared with other jobs took 20–50 times as long as the blocks on one thread."""
    n = len(x)
    if n < 2 * BLAS_BLOCK:
        return x @ matrix
    out = np.empty((n, matrix.shape[1]), np.result_type(x, matrix))
    starts = range(0, n - n % BLAS_BLOCK, BLAS_BLOCK)
    for lo in starts:
        hi = n if lo == starts[-1] else lo + BLAS_BLOCK
        np.matmul(x[lo:hi], matrix, out=out[lo:hi])
    return out


KEEP_BYTES = 16 << 20
"""Largest buffer :func:`work_array` and :func:`reused_array` keep outside
:func:`run_buffers` (16 MiB, the cells of some 70,000 robots): larger arrays are allocated
afresh, as a thread keeps its buffers after a run ends."""

_WORK = threading.local()
_KEPT = threading.local()
_RUN = threading.local()


def kept_bytes() -> float:
    """Largest buffer the calling thread keeps now: :data:`KEEP_BYTES`, or any size within
    :func:`run_buffers`."""
    return float("inf") if getattr(_RUN, "depth", 0) else KEEP_BYTES


@contextmanager
def run_buffers() -> Iterator[None]:
    """Within the block, :func:`work_array` and :func:`reused_array` keep the calling
    thread's buffers of every size, so that the steps of one run reuse them however large
    the fleet; on leaving the outermost block the buffers beyond :data:`KEEP_BYTES` are let
    go (arrays made from them stay valid: they hold their buffer). A million robots'
    cells and neighbour tables allocated afresh every step cost their page faults every
    step (kernel time of both threads: ``benchmarks/million.py``)."""
    _RUN.depth = getattr(_RUN, "depth", 0) + 1
    try:
        yield
    finally:
        _RUN.depth -= 1
        if _RUN.depth == 0:
            release_large_buffers()


def release_large_buffers() -> None:
    """Let go of the calling thread's kept buffers beyond :data:`KEEP_BYTES`."""
    work = _WORK.__dict__
    for key in [key for key, buffer in work.items() if buffer.nbytes > KEEP_BYTES]:
        del work[key]
    for kept in _KEPT.__dict__.values():
        kept[:] = [buffer for buffer in kept if buffer.nbytes <= KEEP_BYTES]


def work_array(key: str, shape: tuple[int, ...], dtype) -> np.ndarray:
    """A C-contiguous work array of ``shape`` for a temporary that does not outlive its
    call, kept per thread under ``key`` and reused by the next call with that key on the
    same thread (grown when too small; contents undefined; not kept beyond
    :data:`KEEP_BYTES` outside :func:`run_buffers`). Arrays of a megabyte allocated afresh
    every step cost their page faults every step (the allocator hands the freed pages
    back): at 10,000 robots the cells' neighbour table alone took 160 faults."""
    size, dtype = prod(shape), np.dtype(dtype)
    if size * dtype.itemsize > kept_bytes():
        return np.empty(shape, dtype)
    pool = _WORK.__dict__
    buffer = pool.get(key)
    if buffer is None or buffer.dtype != dtype or buffer.size < size:
        buffer = pool[key] = np.empty(max(size, 1), dtype)
    return buffer[:size].reshape(shape)


KEPT_PER_KEY = 2
"""Buffers :func:`reused_array` keeps per key and thread: this step's arrays and the last
step's, which a caller still holds while it builds the next."""


def reused_array(key: str, shape: tuple[int, ...], dtype) -> np.ndarray:
    """A C-contiguous array of ``shape`` (contents undefined) to return to the caller,
    made from a buffer the calling thread kept under ``key`` that no array refers to any
    more, else from a new buffer that is then kept (at most :data:`KEPT_PER_KEY`, the
    oldest let go; none beyond :data:`KEEP_BYTES` outside :func:`run_buffers`). An array
    made from a buffer refers to it (numpy's ``base``), and so does every view of it, so a
    buffer is reused only once every array made from it is gone; what a caller keeps is
    never overwritten. Saves the page faults of allocating the cells' megabytes afresh
    every step (:func:`work_array`)."""
    size, dtype = prod(shape), np.dtype(dtype)
    if size * dtype.itemsize > kept_bytes():
        return np.empty(shape, dtype)
    kept = _KEPT.__dict__.setdefault(key, [])
    for buffer in kept:
        if buffer.dtype == dtype and buffer.size >= size and sys.getrefcount(buffer) == _UNUSED:
            return buffer[:size].reshape(shape)
    buffer = np.empty(max(size, 1), dtype)
    kept.append(buffer)
    if len(kept) > KEPT_PER_KEY:
        kept.pop(0)
    return buffer[:size].reshape(shape)


_UNUSED = 3
"""References to a kept buffer that nothing else uses, as :func:`reused_array` counts
them in CPython: the kept list, the loop variable and ``getrefcount``'s argument
(``tests/avoidance/test_cell_kernels.py`` checks that released buffers are reused and
held ones never are)."""
