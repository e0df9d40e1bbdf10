"""Experiment machinery shared by every family: result store, executors, sweeps and
declared reproductions.

* :func:`run_tasks` runs a module-level task function over task dicts (each with a
  unique ``run_id`` and a ``seed``) on the ``serial``, ``process`` (default) or ``dask``
  executor, or any :class:`concurrent.futures.Executor`, recording each finished task at
  once in a Parquet store (many tasks per file) that re-runs resume from.
* :func:`run_sweep` expands a sweep (scenario × grid × seeds) into tasks and runs them.
* :func:`reproduce` runs a declared :class:`Reproduction` (a paper's experiment) on
  :func:`run_sweep` and writes its tables and figures.
* :class:`ResultStore` reads and writes the store; :func:`summarize_sweep` gives means
  per grid combination.
* :func:`batch_cluster` sets up a Dask cluster on SLURM or PBS (dask-jobqueue) for sweeps.
"""

from ..core.lazy import exports

__all__ = [
    "Executor", "ResultStore", "batch_cluster", "deterministic_columns", "run_tasks",
    "SweepPlan", "SweepSpec", "plan_sweep", "run_sweep", "summarize_sweep",
    "Budget", "Reproduction", "ReproductionResult", "reproduce",
]
__getattr__, __dir__ = exports(__name__, {
    ".clusters": ["batch_cluster"],
    ".executors": ["Executor"],
    ".reproduction": ["Budget", "Reproduction", "ReproductionResult", "reproduce"],
    ".store": ["ResultStore", "deterministic_columns"],
    ".sweep": ["SweepPlan", "SweepSpec", "plan_sweep", "run_sweep", "summarize_sweep"],
    ".tasks": ["run_tasks"],
})
