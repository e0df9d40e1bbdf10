"""Reproductions as declarations, run by one driver on :func:`run_sweep`.

A :class:`Reproduction` names a paper's experiment as data: the shipped sweep files it
runs (each scenario × grid × seeds, also runnable alone with ``robofleet sweep``), the
budgets it can run at, and three functions — per-sweep result frames → summary tables,
tables → markdown, tables → figures. :func:`reproduce` is the only driver: every paper's
experiment writes the same files into ``out``, resumes the same way (finished runs are
skipped) and runs on every executor:

``out/runs/<sweep>/``  the Parquet result store of each sweep (many runs per file)
``out/summary.csv``    every summary table, one block per table (column ``table``)
``out/table.md``       the markdown tables
``out/*.png``          the figures

The declarations live in :mod:`robofleet.experiments.reproductions` (one module per
paper); :data:`~robofleet.experiments.reproductions.REPRODUCTIONS` is their table.
"""

from __future__ import annotations

import concurrent.futures
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd

from ..core.config import read_mapping
from ..core import arguments
from ..core.errors import ConfigError
from ..core.files import staged_files
from ..scenarios import catalogue
from .executors import Executor, as_executor
from .store import ERROR_COLUMN
from .sweep import run_sweep

TABLE_FILES = ("summary.csv", "table.md")
"""The tables a reproduction writes into its output directory."""

Frames = dict[str, pd.DataFrame]


@dataclass(frozen=True)
class Budget:
    """How much of an experiment to run.

    Attributes
    ----------
    seeds:
        seeds per grid point of every sweep.
    overrides:
        scenario overrides added to every sweep (e.g. a shorter ``max_steps``).
    grid:
        grid entries replacing the sweep's own (e.g. fewer robot counts).
    """

    seeds: int
    overrides: Mapping[str, Any] = field(default_factory=dict)
    grid: Mapping[str, list] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if isinstance(self.seeds, bool) or not isinstance(self.seeds, int) or self.seeds < 1:
            raise ConfigError(f"Budget: seeds: expected a positive integer, received {self.seeds!r}")


@dataclass(frozen=True)
class Reproduction:
    """One paper's experiment, declared.

    Attributes
    ----------
    name:
        the name ``robofleet reproduce NAME`` takes.
    family:
        the family its scenarios belong to.
    paper:
        authors and year, and the figure or table reproduced.
    description:
        one line.
    sweeps:
        names of shipped sweep files (``sweeps/<name>.yaml``).
    tables:
        ``tables(frames) -> {table name: DataFrame}``, ``frames`` mapping each sweep
        name to its rows (failed runs included, with ``error`` set).
    markdown:
        ``markdown(tables) -> str``, the text of ``table.md``.
    figures:
        ``figures(tables, out) -> [paths]``, drawn into the directory ``out``.
    budgets:
        named budgets; ``smallest`` (a smoke run) and ``default`` are required.
    seed_shares:
        sweep name → share of the budget's seeds that sweep runs (costly sweeps
        run fewer; at least one seed each).
    """

    name: str
    family: str
    paper: str
    description: str
    sweeps: tuple[str, ...]
    tables: Callable[[Frames], dict[str, pd.DataFrame]]
    markdown: Callable[[dict[str, pd.DataFrame]], str]
    figures: Callable[[dict[str, pd.DataFrame], Path], list[Path]]
    budgets: Mapping[str, Budget]
    seed_shares: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for required in ("smallest", "default"):
            if required not in self.budgets:
                raise ConfigError(f"reproduction {self.name}: budgets: expected a {required!r} budget, received {sorted(self.budgets)}")
        for sweep, share in self.seed_shares.items():
            if sweep not in self.sweeps or not 0 < share <= 1:
                raise ConfigError(f"reproduction {self.name}: seed_shares: expected shares in (0, 1] of its own sweeps, "
                                  f"received {sweep!r}: {share!r}")

    def sweep_mapping(self, sweep: str, budget: Budget, seeds: int | None = None) -> dict[str, Any]:
        """The sweep file ``sweep`` with ``budget`` (and a ``seeds`` count, if given) applied."""
        data, _ = read_mapping(catalogue.path(sweep, "sweeps"))
        data["grid"] = {**(data.get("grid") or {}), **{k: list(v) for k, v in budget.grid.items() if k in (data.get("grid") or {})}}
        data["overrides"] = {**(data.get("overrides") or {}), **budget.overrides}
        count = int(seeds if seeds is not None else budget.seeds)
        data["seeds"] = max(1, int(round(count * self.seed_shares.get(sweep, 1.0))))
        data.pop("out", None)
        return data


@dataclass(frozen=True)
class ReproductionResult:
    """What :func:`reproduce` wrote: the per-sweep frames, the tables and the files."""

    frames: Frames
    tables: dict[str, pd.DataFrame]
    markdown: str
    files: list[Path]
    failed: int


def reproduce(
    reproduction: Reproduction,
    out: str | Path | None = None,
    *,
    budget: str = "default",
    seeds: int | None = None,
    executor: str | Executor | concurrent.futures.Executor = "process",
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
) -> ReproductionResult:
    """Run (or resume) a declared reproduction and write its files into ``out``.

    Parameters
    ----------
    reproduction:
        The declaration.
    out:
        Output directory; default ``results/<name>``.
    budget:
        One of the declaration's budgets (``smallest``, ``default``, ...).
    seeds:
        Seeds per grid point, overriding the budget's.
    executor, scheduler, workers, progress:
        As for :func:`robofleet.experiments.run_tasks`.
    """
    arguments.instance(reproduction, Reproduction, "reproduction", "a Reproduction (see robofleet.experiments.reproductions.REPRODUCTIONS)")
    as_executor(executor)
    arguments.path(out, "out", optional=True)
    workers = arguments.count(workers, "workers", minimum=1, optional=True)
    progress = arguments.flag(progress, "progress")
    if not isinstance(budget, str) or budget not in reproduction.budgets:
        raise ConfigError(f"--budget: expected one of {sorted(reproduction.budgets)}, received {budget!r}")
    if seeds is not None and (isinstance(seeds, (bool, np.bool_)) or not isinstance(seeds, (int, np.integer)) or seeds < 1):
        raise ConfigError(f"--seeds: expected a positive integer, received {seeds!r}")
    chosen = reproduction.budgets[budget]
    out_dir = Path(out) if out is not None else Path("results") / reproduction.name
    frames: Frames = {}
    for sweep in reproduction.sweeps:
        mapping = reproduction.sweep_mapping(sweep, chosen, seeds)
        frames[sweep] = run_sweep(mapping, executor=executor, scheduler=scheduler, workers=workers,
                                  progress=progress, out=out_dir / "runs" / sweep)
    tables = reproduction.tables(frames)
    text = reproduction.markdown(tables)
    files = write_tables(tables, text, out_dir)
    files += list(reproduction.figures(tables, out_dir))
    failed = sum(int(frame[ERROR_COLUMN].notna().sum()) for frame in frames.values() if ERROR_COLUMN in frame)
    return ReproductionResult(frames, tables, text, files, failed)


def write_tables(tables: dict[str, pd.DataFrame], text: str, out: Path) -> list[Path]:
    """Write ``summary.csv`` (all tables, column ``table`` first) and ``table.md``, which
    replace the earlier ones together once both are complete (:func:`~robofleet.core.files.staged_files`)."""
    blocks = [table.assign(table=name)[["table", *table.columns]] for name, table in tables.items()]
    summary = pd.concat(blocks, ignore_index=True) if blocks else pd.DataFrame()
    with staged_files(out, TABLE_FILES) as staging:
        summary.to_csv(staging.path / "summary.csv", index=False)
        (staging.path / "table.md").write_text(text, encoding="utf-8")
    return [out / name for name in TABLE_FILES]
