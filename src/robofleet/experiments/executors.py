"""Where tasks run: in this process, in local worker processes, or on a Dask cluster.

Every executor is a generator of ``(task, outcome)`` pairs yielded *as tasks complete*
(not in submission order), so the caller can store each result at once. An outcome is
``("ok", rows)`` or ``("error", message)``: an exception raised by the task function is
caught where it ran and turned into a one-line message, so one failing task never stops
the others. Only a bounded window of tasks is submitted ahead of the results
(:data:`WINDOW_PER_WORKER` per worker process, :data:`DASK_WINDOW_PER_WORKER` on Dask), so
memory stays flat on large sweeps and an interrupted sweep has little work in flight.

Determinism does not depend on the executor: a task's result depends only on the task
(its ``seed`` included), never on which worker ran it or when.
"""

from __future__ import annotations

import enum
import logging
import os
import pickle
import signal
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from types import ModuleType
from typing import TYPE_CHECKING, Any, Callable, Iterator, Mapping

from ..core.errors import ConfigError, RobofleetError

if TYPE_CHECKING:
    from distributed import Client, LocalCluster

Outcome = tuple[str, Any]
TaskFn = Callable[[dict], "dict | list[dict]"]
WINDOW_PER_WORKER = 2  # each worker process has its own queue: a task waits behind at most one other
DASK_WINDOW_PER_WORKER = 16  # hides the scheduler round trip (measured: ~2x throughput on tiny tasks)


class Executor(str, enum.Enum):
    """The executors :func:`robofleet.experiments.run_tasks` accepts."""

    serial = "serial"
    process = "process"
    dask = "dask"


def as_executor(name: str | Executor) -> Executor:
    """Normalise an executor name, listing the valid ones on error."""
    try:
        return Executor(name)
    except ValueError:
        raise ConfigError(f"executor: expected one of {[e.value for e in Executor]}, received {name!r}") from None


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
        return "ok", [dict(r) for r in rows]
    except Exception as exc:  # recorded as a failure row; the sweep goes on
        return "error", one_line(exc)


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


def execute(fn: TaskFn, tasks: list[dict], executor: str | Executor = "process", scheduler: str | None = None, workers: int | None = None) -> Iterator[tuple[dict, Outcome]]:
    """Run ``fn`` on every task with the chosen executor, yielding results as they complete."""
    kind = as_executor(executor)
    if scheduler is not None and kind is not Executor.dask:
        raise ConfigError(f"scheduler: expected None unless executor is 'dask', received {scheduler!r} with executor {kind.value!r}")
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


def run_serial(fn: TaskFn, tasks: list[dict]) -> Iterator[tuple[dict, Outcome]]:
    """Tasks one after the other in this process (debugging, tiny sweeps)."""
    for task in tasks:
        yield task, call_task(fn, task)


def run_processes(fn: TaskFn, tasks: list[dict], workers: int) -> Iterator[tuple[dict, Outcome]]:
    """Tasks on local worker processes, each with its own task queue.

    ``fn`` must be a module-level function (workers receive it by reference). Tasks of one
    seed go to the same worker as far as the load allows (:class:`SeedQueue`), so what a
    worker's process caches for a seed (the coordination family's planned instance, run
    by six variants) is computed once. The pools start and the first tasks are submitted
    before this returns, so worker processes are created before a progress bar starts its
    thread. A worker that dies (e.g. killed by the OS) turns its task, and the tasks
    already queued on it, into failure rows (retried on the next run); its remaining
    tasks go to a fresh process.
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

    def __bool__(self) -> bool:
        return bool(self.groups)

    def next_for(self, worker: int) -> dict | None:
        """The next task for ``worker``, or ``None`` when none is pending."""
        seeds = self.claimed.setdefault(worker, deque())
        while seeds and seeds[0] not in self.groups:
            seeds.popleft()
        if not seeds and self.unclaimed:
            seeds.append(self.unclaimed.popleft())
        seed = seeds[0] if seeds else next(iter(self.groups), None)
        return None if seed is None else self.pop(seed)

    def pop(self, seed: Any) -> dict:
        group = self.groups[seed]
        task = group.popleft()
        if not group:
            del self.groups[seed]
        return task


class ProcessRunner:
    """A bounded window of tasks in flight per worker process (see :func:`run_processes`)."""

    def __init__(self, fn: TaskFn, tasks: list[dict], workers: int):
        self.fn = fn
        self.pending = SeedQueue(tasks)
        self.pools = [self.new_pool() for _ in range(workers)]
        self.in_flight: dict[Future, tuple[int, dict]] = {}
        self.fill()

    @staticmethod
    def new_pool() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=1, initializer=ignore_interrupts)

    def fill(self) -> None:
        for worker in range(len(self.pools)):
            while self.queued(worker) < WINDOW_PER_WORKER and self.pending:
                self.submit(worker, self.pending.next_for(worker))

    def queued(self, worker: int) -> int:
        return sum(1 for owner, _ in self.in_flight.values() if owner == worker)

    def submit(self, worker: int, task: dict) -> None:
        try:
            future = self.pools[worker].submit(call_task, self.fn, task)
        except BrokenProcessPool:  # the worker died: go on with a fresh process
            self.pools[worker].shutdown(wait=False, cancel_futures=True)
            self.pools[worker] = self.new_pool()
            future = self.pools[worker].submit(call_task, self.fn, task)
        self.in_flight[future] = (worker, task)

    def results(self) -> Iterator[tuple[dict, Outcome]]:
        try:
            while self.in_flight:
                done, _ = wait(self.in_flight, return_when=FIRST_COMPLETED)
                for future in done:
                    _, task = self.in_flight.pop(future)
                    exc = future.exception()
                    yield task, (("error", one_line(exc)) if exc is not None else future.result())
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
            dashboard_address=None, silence_logs=logging.ERROR,
        )
        return distributed.Client(cluster), cluster
    try:
        return distributed.Client(scheduler, timeout="10s"), None
    except (OSError, TimeoutError, ValueError) as exc:
        raise RobofleetError(f"scheduler: cannot connect to the Dask scheduler at {scheduler!r} ({one_line(exc)})") from None


def run_dask(fn: TaskFn, tasks: list[dict], scheduler: str | None, workers: int | None) -> Iterator[tuple[dict, Outcome]]:
    """Tasks on a Dask distributed cluster; results come back here and are stored here.

    Connects (or starts the ``LocalCluster``) before returning, so a wrong address fails
    before any progress bar appears. Workers of an external cluster need robofleet (and
    the module defining ``fn``) installed; they never touch the result store, so they
    need no shared file system.
    """
    distributed = import_distributed()
    client, cluster = dask_client(scheduler, workers)
    return dask_results(distributed, client, cluster, fn, tasks, workers)


def dask_results(distributed: ModuleType, client: Client, cluster: LocalCluster | None, fn: TaskFn,
                 tasks: list[dict], workers: int | None) -> Iterator[tuple[dict, Outcome]]:
    """Submit a bounded window of tasks to ``client``; yield results as they complete."""
    try:
        n_workers = len(client.scheduler_info().get("workers", {})) or workers or default_workers()
        window = n_workers * DASK_WINDOW_PER_WORKER
        pending = deque(tasks)
        in_flight: dict[Any, dict] = {}
        completed = distributed.as_completed(with_results=True, raise_errors=False)  # results fetched on the client's loop

        def submit_more() -> None:
            while pending and len(in_flight) < window:
                task = pending.popleft()
                future = client.submit(call_task, fn, task, pure=False)
                in_flight[future.key] = task
                completed.add(future)

        submit_more()
        for future, result in completed:
            task = in_flight.pop(future.key)
            if future.status == "finished":
                outcome = result
            else:  # the worker died or the task was cancelled; result is (type, exc, tb) or exc
                outcome = ("error", one_line(result[1] if isinstance(result, tuple) else result))
            future.release()
            yield task, outcome
            submit_more()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
