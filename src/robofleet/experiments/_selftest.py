"""Small deterministic task functions used by the experiment tests and benchmark.

They live in the package (not in ``tests/``) so that worker processes of every executor,
a Dask ``LocalCluster`` included, can import them by name.
"""

from __future__ import annotations

import os
import time
import uuid
from pathlib import Path

from ..core.rng import as_generator


def noisy_sum(task: dict) -> dict | list[dict]:
    """A seeded computation: statistics of ``n`` standard normal draws.

    Task keys (all optional besides ``seed``): ``n`` (draws, default 4), ``rows`` (return
    a list of that many rows, one per ``part``; none for 0), ``fail`` (raise ``ValueError`` when true),
    ``sleep`` (seconds to wait first), ``crash`` (end the process at once), ``marker_dir`` (write one empty file per call
    there, so tests count calls across processes). The result depends only on the task.
    """
    start = time.perf_counter()
    if task.get("marker_dir"):
        Path(task["marker_dir"], f"{task['run_id']}-{uuid.uuid4().hex}").touch()
    if task.get("crash"):
        os._exit(3)  # a worker process dying abruptly
    if task.get("sleep"):
        time.sleep(float(task["sleep"]))
    if task.get("fail"):
        raise ValueError(f"requested failure of {task['run_id']}\nsecond line not shown")
    draws = as_generator(task["seed"]).standard_normal((max(1, int(task.get("rows", 1))), int(task.get("n", 4))))
    rows = [
        {"part": part, "total": float(d.sum()), "largest": float(d.max()), "label": f"p{part}", "compute_seconds": time.perf_counter() - start}
        for part, d in enumerate(draws)
    ]
    return rows[:int(task["rows"])] if "rows" in task else rows[0]


def trivial(task: dict) -> dict:
    """Almost no work: measures the per-task overhead of an executor."""
    return {"value": task["seed"] % 7}
