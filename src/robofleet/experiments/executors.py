"""Where tasks run: in this process, in local worker processes, on a Dask cluster, or on
any :class:`concurrent.futures.Executor` (threads, MPI, a job array).

Every executor is a generator of result lists ``[(task, outcome), ...]`` yielded *as
chunks of tasks complete* (not in submission order), so the caller can store each result
at once. An outcome is ``("ok", rows)`` or ``("error", message)``: an exception raised by
the task function is caught where it ran and turned into a one-line message, so one
failing task never stops the others.

Tasks travel in chunks (:class:`ChunkSizer`): one task at first, then as many as run in
about :data:`CHUNK_SECONDS` by the times measured so far, so tasks of a millisecond cost
one round trip per hundred, while slow tasks still go one by one. Only a bounded window
of chunks is submitted ahead of the results (:data:`WINDOW_PER_WORKER` per worker), so
memory stays flat on large sweeps and an interrupted sweep has little work in flight.

Determinism does not depend on the executor: a task's result depends only on the task
(its ``seed`` included), never on which worker ran it, in which chunk, or when.
"""

from __future__ import annotations

import concurrent.futures
import enum
import logging
import math
import os
import pickle
import signal
import time
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from types import ModuleType
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any

from ..core.errors import ConfigError, RobofleetError

if TYPE_CHECKING:
    from distributed import Client, LocalCluster

Outcome = tuple[str, Any]
TaskFn = Callable[[dict], "dict | list[dict]"]
Results = Iterator[list[tuple[dict, Outcome]]]
WINDOW_PER_WORKER = 2  # chunks in flight per worker: one running, one waiting behind it
DASK_WINDOW_PER_WORKER = 4  # hides the scheduler round trip
CHUNK_SECONDS = 0.1
"""The compute time a chunk of tasks aims at (a round trip costs well under a millisecond)."""
MAX_CHUNK = 4096
"""The most tasks one chunk holds."""
CHUNK_GROWTH = 4
"""A chunk holds at most this many times the tasks of the largest chunk timed so far."""


class Executor(str, enum.Enum):
    """The executors :func:`robofleet.experiments.run_tasks` accepts by name (it also
    accepts any :class:`concurrent.futures.Executor` instance)."""

    serial = "serial"
    process = "process"
    dask = "dask"


def as_executor(name: str | Executor | concurrent.futures.Executor) -> Executor | concurrent.futures.Executor:
    """Normalise an executor name (or pass a :class:`concurrent.futures.Executor` through),
    listing the valid ones on error."""
    if isinstance(name, concurrent.futures.Executor):
        return name
    try:
        return Executor(name)
    except ValueError:
        raise ConfigError(f"executor: expected one of {[e.value for e in Executor]} or a concurrent.futures.Executor, "
                          f"received {name!r}") from None


def one_line(exc: BaseException) -> str:
    """``"TypeName: first line of the message"``."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def call_task(fn: TaskFn, task: dict) -> Outcome:
    """Run ``fn(task)`` and check its result; never raises an ``Exception``.

    Returns ``("ok", rows)`` with ``rows`` a list of dicts, or ``("error", message)``.
    """
    try:
        result = fn(dict(task))
        rows = [result] if isinstance(result, Mapping) else result
        if not isinstance(rows, list) or not all(isinstance(r, Mapping) for r in rows):
            raise TypeError(f"the task function must return a dict or a list of dicts, received {type(result).__name__}")
        if any("error" in r for r in rows):
            raise ValueError("the task function returned the reserved column 'error' (raise an exception instead)")
        return "ok", [r if type(r) is dict else dict(r) for r in rows]
    except Exception as exc:  # recorded as a failure row; the sweep goes on
        return "error", one_line(exc)


def call_chunk(fn: TaskFn, tasks: list[dict]) -> tuple[list[Outcome], float]:
    """Run ``fn`` on each task of a chunk (:func:`call_task`); returns the outcomes and
    the seconds they took (which size the next chunks)."""
    start = time.perf_counter()
    outcomes = [call_task(fn, task) for task in tasks]
    return outcomes, time.perf_counter() - start


class ChunkSizer:
    """How many tasks the next chunk holds.

    The first chunk holds one task; then ``CHUNK_SECONDS / (seconds per task)``, with
    the seconds per task measured on the chunks that came back (a running mean weighted
    towards the latest), growing by at most :data:`CHUNK_GROWTH` times the largest
    chunk timed so far, at most :data:`MAX_CHUNK`, and at most an even share of the
    pending tasks over twice the workers (so the last chunks still keep every worker busy).
    """

    def __init__(self, workers: int):
        self.workers = workers
        self.per_task: float | None = None
        self.timed = 0

    def size(self, pending: int) -> int:
        share = max(1, math.ceil(pending / (2 * self.workers)))
        if self.per_task is None:
            return 1
        wanted = CHUNK_SECONDS / max(self.per_task, 1e-9)
        return int(max(1, min(wanted, CHUNK_GROWTH * self.timed, MAX_CHUNK, share)))

    def record(self, tasks: int, seconds: float) -> None:
        per_task = seconds / max(tasks, 1)
        self.per_task = per_task if self.per_task is None else 0.5 * self.per_task + 0.5 * per_task
        self.timed = max(self.timed, tasks)


def chunk_outcomes(chunk: list[dict], future: Any, exc: BaseException | None, sizer: ChunkSizer) -> list[tuple[dict, Outcome]]:
    """The results of a finished chunk future; a chunk whose worker died fails each of its tasks."""
    if exc is not None:
        return [(task, ("error", one_line(exc))) for task in chunk]
    outcomes, seconds = future.result()
    sizer.record(len(chunk), seconds)
    return list(zip(chunk, outcomes))


def ignore_interrupts() -> None:
    """Worker initializer: Ctrl-C is handled by the driving process alone, which stops
    the workers itself, so an interrupt is never recorded as a task failure."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def default_workers() -> int:
    """Worker count when none is given: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def check_workers(workers: int | None) -> int:
    if workers is None:
        return default_workers()
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers: expected a positive integer or None, received {workers!r}")
    return workers


def execute(fn: TaskFn, tasks: list[dict], executor: str | Executor | concurrent.futures.Executor = "process",
            scheduler: str | None = None, workers: int | None = None) -> Results:
    """Run ``fn`` on every task with the chosen executor, yielding result lists as chunks complete."""
    kind = as_executor(executor)
    if scheduler is not None and kind is not Executor.dask:
        received = kind.value if isinstance(kind, Executor) else type(kind).__name__
        raise ConfigError(f"scheduler: expected None unless executor is 'dask', received {scheduler!r} with executor {received!r}")
    if isinstance(kind, concurrent.futures.Executor):
        if isinstance(kind, ProcessPoolExecutor):
            check_picklable(fn)
        return PoolRunner(kind, fn, tasks, check_workers(workers) if workers is not None else pool_workers(kind)).results()
    if kind is Executor.serial:
        return run_serial(fn, tasks)
    if kind is Executor.process:
        check_picklable(fn)
        return run_processes(fn, tasks, check_workers(workers))
    return run_dask(fn, tasks, scheduler, None if workers is None else check_workers(workers))


def check_picklable(fn: TaskFn) -> None:
    """Worker processes receive ``fn`` by reference: it must be a module-level function
    (or a ``functools.partial`` of one)."""
    try:
        pickle.dumps(fn)
    except (pickle.PicklingError, AttributeError, TypeError) as exc:
        raise ConfigError(f"fn: expected a module-level function that worker processes can import, received {fn!r} ({one_line(exc)})") from None


def run_serial(fn: TaskFn, tasks: list[dict]) -> Results:
    """Tasks one after the other in this process, each result yielded at once."""
    for task in tasks:
        yield [(task, call_task(fn, task))]


def pool_workers(pool: concurrent.futures.Executor) -> int:
    """The workers of an executor instance, where it tells (else the CPUs available)."""
    count = getattr(pool, "_max_workers", None)
    return count if isinstance(count, int) and count > 0 else default_workers()


class PoolRunner:
    """Chunks of tasks on any :class:`concurrent.futures.Executor` the caller owns (it is
    neither shut down nor waited for here; chunks not started when the consumer stops are
    cancelled). The pool receives ``call_chunk(fn, tasks)`` calls, so a pool of other
    processes (MPI ranks, a job array) needs ``fn`` importable by name there."""

    def __init__(self, pool: concurrent.futures.Executor, fn: TaskFn, tasks: list[dict], workers: int):
        self.pool, self.fn = pool, fn
        self.pending = deque(tasks)
        self.window = WINDOW_PER_WORKER * workers
        self.sizer = ChunkSizer(workers)
        self.in_flight: dict[Future, list[dict]] = {}
        self.fill()

    def fill(self) -> None:
        while self.pending and len(self.in_flight) < self.window:
            chunk = [self.pending.popleft() for _ in range(min(len(self.pending), self.sizer.size(len(self.pending))))]
            self.in_flight[self.pool.submit(call_chunk, self.fn, chunk)] = chunk

    def results(self) -> Results:
        try:
            while self.in_flight:
                done, _ = wait(self.in_flight, return_when=FIRST_COMPLETED)
                for future in done:
                    chunk = self.in_flight.pop(future)
                    yield chunk_outcomes(chunk, future, future.exception(), self.sizer)
                self.fill()
        finally:
            for future in self.in_flight:
                future.cancel()


def run_processes(fn: TaskFn, tasks: list[dict], workers: int) -> Results:
    """Tasks on local worker processes, each with its own queue of chunks.

    ``fn`` must be a module-level function (workers receive it by reference). Tasks of one
    seed go to the same worker as far as the load allows (:class:`SeedQueue`), so what a
    worker's process caches for a seed (the coordination family's planned instance, run
    by six variants) is computed once. The pools start and the first chunks are submitted
    before this returns, so worker processes are created before a progress bar starts its
    thread. A worker that dies (e.g. killed by the OS) turns the tasks of its chunk, and
    of the chunk queued behind it, into failure rows (retried on the next run); its
    remaining tasks go to a fresh process.
    """
    return ProcessRunner(fn, tasks, workers).results()


class SeedQueue:
    """Pending tasks grouped by ``seed`` (groups in order of first appearance, tasks in
    order within a group). A worker takes the tasks of the seeds it has claimed, then
    claims the next unclaimed seed, and when none is left takes the first pending task of
    another worker's seed. Which worker runs a task never changes its rows."""

    def __init__(self, tasks: list[dict]):
        self.groups: dict[Any, deque[dict]] = {}
        for task in tasks:
            self.groups.setdefault(task.get("seed"), deque()).append(task)
        self.unclaimed = deque(self.groups)
        self.claimed: dict[int, deque] = {}
        self.count = len(tasks)

    def __bool__(self) -> bool:
        return bool(self.groups)

    def __len__(self) -> int:
        return self.count

    def next_for(self, worker: int) -> dict | None:
        """The next task for ``worker``, or ``None`` when none is pending."""
        seeds = self.claimed.setdefault(worker, deque())
        while seeds and seeds[0] not in self.groups:
            seeds.popleft()
        if not seeds and self.unclaimed:
            seeds.append(self.unclaimed.popleft())
        seed = seeds[0] if seeds else next(iter(self.groups), None)
        return None if seed is None else self.pop(seed)

    def chunk_for(self, worker: int, size: int) -> list[dict]:
        """Up to ``size`` next tasks for ``worker``."""
        chunk = []
        while len(chunk) < size and self.groups:
            chunk.append(self.next_for(worker))
        return chunk

    def pop(self, seed: Any) -> dict:
        group = self.groups[seed]
        task = group.popleft()
        self.count -= 1
        if not group:
            del self.groups[seed]
        return task


class ProcessRunner:
    """A bounded window of chunks in flight per worker process (see :func:`run_processes`)."""

    def __init__(self, fn: TaskFn, tasks: list[dict], workers: int):
        self.fn = fn
        self.pending = SeedQueue(tasks)
        self.sizer = ChunkSizer(workers)
        self.pools = [self.new_pool() for _ in range(workers)]
        self.in_flight: dict[Future, tuple[int, list[dict]]] = {}
        self.fill()

    @staticmethod
    def new_pool() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=1, initializer=ignore_interrupts)

    def fill(self) -> None:
        for worker in range(len(self.pools)):
            while self.queued(worker) < WINDOW_PER_WORKER and self.pending:
                self.submit(worker, self.pending.chunk_for(worker, self.sizer.size(len(self.pending))))

    def queued(self, worker: int) -> int:
        return sum(1 for owner, _ in self.in_flight.values() if owner == worker)

    def submit(self, worker: int, chunk: list[dict]) -> None:
        try:
            future = self.pools[worker].submit(call_chunk, self.fn, chunk)
        except BrokenProcessPool:  # the worker died: go on with a fresh process
            self.pools[worker].shutdown(wait=False, cancel_futures=True)
            self.pools[worker] = self.new_pool()
            future = self.pools[worker].submit(call_chunk, self.fn, chunk)
        self.in_flight[future] = (worker, chunk)

    def results(self) -> Results:
        try:
            while self.in_flight:
                done, _ = wait(self.in_flight, return_when=FIRST_COMPLETED)
                for future in done:
                    _, chunk = self.in_flight.pop(future)
                    yield chunk_outcomes(chunk, future, future.exception(), self.sizer)
                self.fill()
        except BaseException:  # Ctrl-C, or the consumer stopped: drop the tasks in flight
            self.stop_workers()
            raise
        finally:
            for pool in self.pools:
                pool.shutdown(wait=True, cancel_futures=True)

    def stop_workers(self) -> None:
        """End the worker processes now (their running tasks are lost, nothing is stored)."""
        for pool in self.pools:
            processes = getattr(pool, "_processes", None) or {}  # no public API before Python 3.14
            for process in list(processes.values()):
                process.terminate()


def import_distributed() -> ModuleType:
    """The ``distributed`` package, or a clear error naming the optional extra."""
    try:
        import distributed
    except ImportError:
        raise RobofleetError("executor 'dask' needs the optional dependency dask[distributed]: pip install 'robofleet[dask]'") from None
    return distributed


def dask_client(scheduler: str | None, workers: int | None) -> tuple[Client, LocalCluster | None]:
    """A ``distributed.Client`` on ``scheduler``, or on a new ``LocalCluster``.

    Returns ``(client, cluster)``; ``cluster`` is ``None`` for an external scheduler.
    A ``LocalCluster`` has ``workers`` single-threaded worker processes.
    """
    distributed = import_distributed()
    if scheduler is None:
        cluster = distributed.LocalCluster(
            n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
            dashboard_address=":0", silence_logs=logging.ERROR,
        )
        return distributed.Client(cluster), cluster
    try:
        return distributed.Client(scheduler, timeout="10s"), None
    except (OSError, TimeoutError, ValueError) as exc:
        raise RobofleetError(f"scheduler: cannot connect to the Dask scheduler at {scheduler!r} ({one_line(exc)})") from None


def run_dask(fn: TaskFn, tasks: list[dict], scheduler: str | None, workers: int | None) -> Results:
    """Chunks of tasks on a Dask distributed cluster; results come back here and are stored here.

    Connects (or starts the ``LocalCluster``) before returning, so a wrong address fails
    before any progress bar appears. Workers of an external cluster need robofleet (and
    the module defining ``fn``) installed; they never touch the result store, so they
    need no shared file system.
    """
    distributed = import_distributed()
    client, cluster = dask_client(scheduler, workers)
    return dask_results(distributed, client, cluster, fn, tasks, workers)


def dask_results(distributed: ModuleType, client: Client, cluster: LocalCluster | None, fn: TaskFn,
                 tasks: list[dict], workers: int | None) -> Results:
    """Submit a bounded window of chunks to ``client``; yield their results as they complete."""
    try:
        n_workers = len(client.scheduler_info().get("workers", {})) or workers or default_workers()
        window = n_workers * DASK_WINDOW_PER_WORKER
        sizer = ChunkSizer(n_workers)
        pending = deque(tasks)
        in_flight: dict[Any, list[dict]] = {}
        completed = distributed.as_completed(with_results=True, raise_errors=False)  # results fetched on the client's loop

        def submit_more() -> None:
            while pending and len(in_flight) < window:
                chunk = [pending.popleft() for _ in range(min(len(pending), sizer.size(len(pending))))]
                future = client.submit(call_chunk, fn, chunk, pure=False)
                in_flight[future.key] = chunk
                completed.add(future)

        submit_more()
        for future, result in completed:
            chunk = in_flight.pop(future.key)
            if future.status == "finished":
                sizer.record(len(chunk), result[1])
                yield list(zip(chunk, result[0]))
            else:  # the worker died or the task was cancelled; result is (type, exc, tb) or exc
                message = one_line(result[1] if isinstance(result, tuple) else result)
                yield [(task, ("error", message)) for task in chunk]
            future.release()
            submit_more()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
