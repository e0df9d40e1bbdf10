"""``run_tasks``: run a task function over many tasks into a resumable result store."""

from __future__ import annotations

import concurrent.futures
from pathlib import Path
from typing import Iterable, Mapping

import pandas as pd

from ..core import arguments
from ..core.errors import ConfigError, Interrupted, short_repr
from ..core.progress import tracked
from .executors import Executor, Results, TaskFn, as_executor, execute
from .store import ResultStore, check_tasks


def run_tasks(
    fn: TaskFn,
    tasks: Iterable[Mapping],
    store: str | Path | ResultStore,
    *,
    executor: str | Executor | concurrent.futures.Executor = "process",
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
) -> pd.DataFrame:
    """Run ``fn`` on every task not yet in ``store``, storing each result as it completes.

    Parameters
    ----------
    fn:
        A module-level function ``fn(task) -> dict | list[dict]`` of scalar columns (a
        list when one task yields several rows). It must be importable by name in worker
        processes. An exception it raises becomes a failure row (see below).
    tasks:
        Dicts, each with a unique ``run_id`` (str) and a ``seed`` (int ≥ 0), plus scalar
        parameters. The key ``error`` is reserved.
    store:
        Directory of the Parquet dataset (or a :class:`ResultStore`). Each finished task
        is appended at once to the store's journal, with the task's fields merged into
        its rows, and the tasks are written many per Parquet file (atomically); tasks
        whose ``run_id`` already finished are skipped, so a killed sweep resumes where it
        stopped and loses only the tasks that were running.
    executor:
        ``"serial"``, ``"process"`` (default: local worker processes), ``"dask"``, or any
        :class:`concurrent.futures.Executor` instance (a ``ThreadPoolExecutor``, an MPI or
        job-array executor), which receives calls ``call_chunk(fn, tasks)`` and is left
        running (``fn`` must then be importable where the executor runs it).
    scheduler:
        With ``"dask"``: a scheduler address (``"tcp://host:8786"``), or ``None`` to
        start a ``LocalCluster`` for this call.
    workers:
        Number of local worker processes (``process``, or the ``LocalCluster`` of
        ``dask``); default: the CPUs available to this process. With an executor
        instance, how many chunks it runs at once (default: its ``_max_workers`` if it
        has one, else the CPUs available).
    progress:
        Show a progress bar with ETA.

    Returns
    -------
    pandas.DataFrame
        Every row in the store, earlier runs included, ordered by ``run_id``; the
        columns ``run_id``, ``seed``, the others by name, and ``error`` (whichever
        executor ran the tasks and however a killed call was resumed). A task
        that raised has one row holding its fields and ``error`` (``"TypeName: message"``);
        ``error`` is ``None`` elsewhere. Failed tasks are retried on the next call.

    Raises
    ------
    ConfigError
        On malformed tasks (missing/duplicate ``run_id``, bad ``seed``) or arguments.
    StoreBusyError
        When another process is writing to the same store (one writer at a time).
    StoreFormatError
        When a file of the store was written in a later store format (one line naming it).
    Interrupted
        On Ctrl-C (a ``KeyboardInterrupt``): finished runs are kept, and the message says
        how many are stored and that the same call resumes.
    """
    arguments.function(fn, "fn")
    checked = check_tasks(arguments.sequence(tasks, "tasks", "task dicts"))
    kind = as_executor(executor)
    workers = arguments.count(workers, "workers", minimum=1, optional=True)
    progress = arguments.flag(progress, "progress")
    store = store if isinstance(store, ResultStore) else ResultStore(arguments.path(store, "store"))
    try:
        blocking = next((p for p in (store.directory, *store.directory.parents) if p.exists() and not p.is_dir()), None)
    except (OSError, ValueError) as exc:  # a name too long, a NUL byte
        raise ConfigError(f"store: expected a usable directory path, received {short_repr(str(store.directory))} "
                          f"({getattr(exc, 'strerror', None) or exc})") from None
    if blocking is not None:
        raise ConfigError(f"store: expected a directory, received {store.directory} ({blocking} is a file)")
    with store.writer_lock():
        store.recover()
        finished = store.finished_ids()
        pending = [t for t in checked if t["run_id"] not in finished]
        if pending:
            store_results(store, execute(fn, pending, kind, scheduler, workers), [t["run_id"] for t in checked], len(pending), progress)
        store.tidy()
        return store.read()


def store_results(store: ResultStore, results: Results, run_ids: list[str], pending: int, progress: bool) -> None:
    """Write the executor's results into ``store`` as they come (many tasks per file);
    on Ctrl-C keep what finished and raise :class:`Interrupted` saying how to resume."""
    skipped = len(run_ids) - pending
    label = f"{pending} runs" + (f" ({skipped} already done)" if skipped else "")
    try:
        with tracked(pending, label, enabled=progress) as advance, store.batches() as batch:
            for chunk in results:
                batch.add(chunk)
                advance(len(chunk))
    except KeyboardInterrupt:
        stored = len(store.finished_ids().intersection(run_ids))
        raise Interrupted(f"interrupted: {stored} of {len(run_ids)} runs stored in {store.directory}; "
                          "rerun the same command to resume") from None
    finally:
        results.close()
