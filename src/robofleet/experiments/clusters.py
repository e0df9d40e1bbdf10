"""Dask clusters on batch systems (SLURM, PBS) through dask-jobqueue, set up for sweeps.

:func:`batch_cluster` returns a dask-jobqueue cluster whose every batch job runs
``cores`` single-threaded Dask worker processes (one per core, each with one thread for
numpy, numba and BLAS, so that the compiled kernels of parallel runs do not compete for
cores). Its scheduler runs in the calling process; ``cluster.scale(jobs=n)`` submits the
jobs, and a sweep runs on it with ``executor="dask", scheduler=cluster.scheduler_address``.
The workers only compute: results come back to the calling process, which alone writes
the result store, so the jobs need robofleet installed but no shared file system.
"""

from __future__ import annotations

import signal
import threading
from types import ModuleType
from typing import TYPE_CHECKING, Any, Sequence

from ..core import arguments
from ..core.errors import ConfigError, RobofleetError

if TYPE_CHECKING:
    from dask_jobqueue.core import JobQueueCluster

BATCH_SYSTEMS = {"slurm": "SLURMCluster", "pbs": "PBSCluster"}
"""The batch systems :func:`batch_cluster` sets up, and their dask-jobqueue classes."""
ONE_THREAD_EACH = ("export OMP_NUM_THREADS=1", "export OPENBLAS_NUM_THREADS=1", "export MKL_NUM_THREADS=1",
                   "export NUMBA_NUM_THREADS=1")
"""Lines every job script runs before starting its workers: one thread per worker process."""


def batch_cluster(system: str, *, cores: int, memory: str, walltime: str = "01:00:00", queue: str | None = None,
                  account: str | None = None, job_script_prologue: Sequence[str] = (), **options: Any) -> JobQueueCluster:
    """A dask-jobqueue cluster for sweeps on ``system`` (``"slurm"`` or ``"pbs"``).

    Parameters
    ----------
    cores:
        Cores per batch job; each job runs that many single-threaded worker processes.
    memory:
        Memory per job (``"16GB"``), shared evenly by its worker processes.
    walltime, queue, account:
        The job's time limit (``"HH:MM:SS"``), queue (SLURM partition) and account.
    job_script_prologue:
        More shell lines run before the workers start (``"module load python"``,
        ``"source ~/venv/bin/activate"``), after :data:`ONE_THREAD_EACH`.
    options:
        Passed to the dask-jobqueue class as they are (``job_extra_directives``,
        ``interface``, ``local_directory``, ...).

    Raises
    ------
    ConfigError
        An unknown ``system`` or a non-positive ``cores``.
    RobofleetError
        When dask-jobqueue is not installed (``pip install 'robofleet[dask]'``).
    """
    if not isinstance(system, str) or system not in BATCH_SYSTEMS:
        raise ConfigError(f"system: expected one of {sorted(BATCH_SYSTEMS)}, received {system!r}")
    cores = arguments.count(cores, "cores", minimum=1)
    cluster_class = getattr(import_jobqueue(), BATCH_SYSTEMS[system])
    return cluster_class(cores=cores, processes=cores, memory=memory, walltime=walltime, queue=queue, account=account,
                         job_script_prologue=[*ONE_THREAD_EACH, *job_script_prologue], **options)


def import_jobqueue() -> ModuleType:
    """The ``dask_jobqueue`` package, imported with Ctrl-C left as it was.

    Importing dask-jobqueue replaces the process's SIGINT handler with one that exits
    (``sys.exit``), which would turn Ctrl-C during a sweep into an exit without the
    one-line "interrupted" message; the earlier handler is put back.

    Raises
    ------
    RobofleetError
        When dask-jobqueue is not installed (``pip install 'robofleet[dask]'``).
    """
    main = threading.current_thread() is threading.main_thread()
    handler = signal.getsignal(signal.SIGINT) if main else None
    try:
        import dask_jobqueue
    except ImportError:
        raise RobofleetError("batch clusters need the optional dependency dask-jobqueue: pip install 'robofleet[dask]'") from None
    finally:
        if main and handler is not None:
            signal.signal(signal.SIGINT, handler)
    return dask_jobqueue
