"""The result store: a directory holding a Parquet dataset, one file per finished task.

Layout
------
``<store>/run-<id>.parquet``
    The rows of a task that finished (its fields merged into every row).
``<store>/error-<id>.parquet``
    One row for a task that raised: its fields plus ``error``, the one-line message.
``<store>/.<name>.tmp-<pid>-<hex>.parquet``
    A file being written. Every file is written under such a hidden name and then
    renamed with :func:`os.replace`, which is atomic on POSIX and Windows
    (:func:`robofleet.core.files.replacing`), so a process killed mid-write leaves either
    the complete file or only a hidden temporary that readers ignore (Parquet readers
    skip names starting with ``.``).

``<store>/_damaged/``
    Files found damaged (truncated by a crash, or not Parquet at all), set aside with one
    warning each; their tasks count as not finished and run again.

Every write is fsynced before the rename and the directory after it.

``<id>`` is the task's ``run_id`` percent-encoded (:func:`urllib.parse.quote`), so any
string is a valid run id and the set of finished ids is read from the directory listing
alone, without opening a file.

Failures are kept (they show up in :meth:`ResultStore.read` with their ``error``) but a
failed task counts as *not finished*: the next run of the same tasks retries it, and its
``run-`` file then replaces the ``error-`` file. The store has one writer at a time (the
process driving the sweep, holding ``<store>/.writer.lock``); a second sweep on the same
directory is refused with one line; workers only compute.

Columns whose name ends in ``_seconds`` are wall-clock timings: they differ between two
runs of the same seed, and :func:`deterministic_columns` leaves them out.
"""

from __future__ import annotations

import json
import os
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping
from urllib.parse import quote, unquote

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

try:
    import fcntl
except ImportError:  # Windows: no advisory locks, the store then assumes one writer
    fcntl = None

from ..core import arguments
from ..core.errors import ConfigError
from ..core.files import is_temporary, replacing
from ..core.trace import to_plain

RUN_PREFIX = "run-"
ERROR_PREFIX = "error-"
SUFFIX = ".parquet"
ERROR_COLUMN = "error"
TIMING_SUFFIX = "_seconds"
MAX_NAME_LENGTH = 240  # most file systems allow 255 bytes per name
DAMAGED_FOLDER = "_damaged"
LOCK_NAME = ".writer.lock"


def file_stem(run_id: str) -> str:
    """The file-name-safe encoding of ``run_id`` (inverse: :func:`urllib.parse.unquote`)."""
    return quote(run_id, safe="")


def check_run_id(run_id: Any, where: str = "task") -> str:
    """Return ``run_id`` if it is a non-empty string short enough to name a file."""
    if not isinstance(run_id, str) or not run_id:
        raise ConfigError(f"{where}: run_id: expected a non-empty string, received {run_id!r}")
    if len(ERROR_PREFIX + file_stem(run_id) + SUFFIX) > MAX_NAME_LENGTH:
        raise ConfigError(f"{where}: run_id: expected at most ~200 characters once percent-encoded, received {len(run_id)} characters")
    return run_id


def cell_value(value: Any) -> Any:
    """A Parquet-friendly scalar: numpy scalars become Python, lists/dicts become JSON text."""
    value = to_plain(value)
    if isinstance(value, (list, dict)):
        return json.dumps(to_plain(value, json_safe=True), sort_keys=True, allow_nan=False)
    return value


class ResultStore:
    """A directory of per-task Parquet files (see the module docstring for the layout).

    Parameters
    ----------
    directory:
        Created on the first write if missing.
    """

    def __init__(self, directory: str | Path):
        self.directory = arguments.path(directory, "directory")

    def __repr__(self) -> str:
        return f"ResultStore({str(self.directory)!r})"

    # -- listing -----------------------------------------------------------------
    def _files(self, prefix: str) -> dict[str, Path]:
        if not self.directory.is_dir():
            return {}
        out = {}
        for entry in os.scandir(self.directory):
            name = entry.name
            if name.startswith(prefix) and name.endswith(SUFFIX) and entry.is_file():
                out[unquote(name[len(prefix) : -len(SUFFIX)])] = Path(entry.path)
        return out

    def finished_ids(self) -> set[str]:
        """Run ids whose task finished without error (these are skipped on re-runs)."""
        return set(self._files(RUN_PREFIX))

    def failed_ids(self) -> set[str]:
        """Run ids whose last attempt raised and that have not finished since."""
        return set(self._files(ERROR_PREFIX)) - self.finished_ids()

    def temporary_files(self) -> list[Path]:
        """Hidden files left by writes that were interrupted."""
        if not self.directory.is_dir():
            return []
        return sorted(p for p in self.directory.iterdir() if is_temporary(p))

    def remove_temporaries(self) -> int:
        """Delete files left by interrupted writes; returns how many were removed.

        Call it only while no other process writes to this store.
        """
        paths = self.temporary_files()
        for path in paths:
            path.unlink(missing_ok=True)
        return len(paths)

    # -- writing -----------------------------------------------------------------
    def write_rows(self, task: Mapping[str, Any], rows: list[Mapping[str, Any]]) -> Path:
        """Store the rows of a finished task, each merged with the task's fields.

        The task's fields come first and win over a row key of the same name. A task
        that produced no rows is still recorded (a file with no rows), so it is not rerun.
        """
        fields = {k: cell_value(v) for k, v in task.items()}
        merged = [{**fields, **{k: cell_value(v) for k, v in row.items() if k not in fields}} for row in rows]
        table = rows_to_table(merged) if merged else empty_table(fields)
        run_id = str(task["run_id"])
        path = self._atomic_write(RUN_PREFIX + file_stem(run_id) + SUFFIX, table)
        (self.directory / (ERROR_PREFIX + file_stem(run_id) + SUFFIX)).unlink(missing_ok=True)
        return path

    def write_error(self, task: Mapping[str, Any], message: str) -> Path:
        """Store one row for a task that raised: its fields plus ``error = message``."""
        row = {k: cell_value(v) for k, v in task.items()}
        row[ERROR_COLUMN] = str(message)
        return self._atomic_write(ERROR_PREFIX + file_stem(str(task["run_id"])) + SUFFIX, rows_to_table([row]))

    def _atomic_write(self, name: str, table: pa.Table) -> Path:
        """Write one store file through :func:`~robofleet.core.files.replacing`: after a
        crash it is either complete or absent."""
        with replacing(self.directory / name) as temp:
            pq.write_table(table, temp)
        return self.directory / name

    # -- one writer --------------------------------------------------------------
    @contextmanager
    def writer_lock(self) -> Iterator[None]:
        """Hold the store's writer lock (``<store>/.writer.lock``, an advisory ``flock``
        released by the OS if the process dies) for the duration of the block.

        Raises
        ------
        StoreBusyError
            If another process holds it: a second sweep on the same directory is refused
            rather than racing the first one. (Where ``fcntl`` is missing, e.g. Windows,
            there is no lock and the store assumes one writer.)
        """
        if fcntl is None:
            yield
            return
        self.directory.mkdir(parents=True, exist_ok=True)
        with open(self.directory / LOCK_NAME, "a+") as handle:
            try:
                fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                handle.seek(0)
                holder = handle.read().strip() or "?"
                raise StoreBusyError(f"store: expected a store no other sweep is writing to, received {self.directory}, "
                                     f"which process {holder} is writing; wait for it or choose another --out") from None
            handle.seek(0)
            handle.truncate()
            handle.write(str(os.getpid()))
            handle.flush()
            try:
                yield
            finally:
                fcntl.flock(handle.fileno(), fcntl.LOCK_UN)

    # -- one schema --------------------------------------------------------------
    def unify_columns(self) -> int:
        """Give every store file the same columns and types (the union of all files', with
        nulls where a file lacks a column), so that ``pandas.read_parquet(store)`` and
        ``polars.read_parquet(store / "*.parquet")`` read every row. Rewrites only the files
        that differ; returns how many were rewritten. Call it only from the store's writer.
        """
        paths = [*self._files(RUN_PREFIX).values(), *self._files(ERROR_PREFIX).values()]
        schemas = {path: pq.read_schema(path) for path in paths}
        if len({schema for schema in schemas.values()}) <= 1:
            return 0
        unified = pa.unify_schemas(list(schemas.values()), promote_options="permissive")
        rewritten = 0
        for path, schema in schemas.items():
            if not schema.equals(unified):
                self._atomic_write(path.name, conform(read_parquet(path), unified))
                rewritten += 1
        return rewritten

    # -- damage ------------------------------------------------------------------
    def set_aside(self, path: Path, reason: str) -> Path:
        """Move a damaged store file into ``<store>/_damaged/`` (readers skip ``_`` folders)
        and warn once; its task then counts as not finished and is run again."""
        target = self.directory / DAMAGED_FOLDER / path.name
        target.parent.mkdir(exist_ok=True)
        os.replace(path, target)
        warnings.warn(DamagedRunWarning(f"{path}: set aside as {target} ({reason}); its run is redone"), stacklevel=2)
        return target

    def set_aside_damaged(self) -> list[Path]:
        """Set aside every store file that is not a complete Parquet file (a truncated or
        foreign file: no ``PAR1`` magic at both ends); returns the files moved."""
        moved = []
        for path in [*self._files(RUN_PREFIX).values(), *self._files(ERROR_PREFIX).values()]:
            if not has_parquet_magic(path):
                moved.append(self.set_aside(path, "not a complete Parquet file"))
        return moved

    # -- reading -----------------------------------------------------------------
    def read(self) -> pd.DataFrame:
        """Every stored row (finished and failed tasks), ordered by ``run_id``.

        The frame always has the columns ``run_id``, ``seed`` and ``error`` (``None`` on
        rows of tasks that finished).
        """
        finished = self._files(RUN_PREFIX)
        failed = {k: v for k, v in self._files(ERROR_PREFIX).items() if k not in finished}
        every = {**failed, **finished}
        paths = [every[k] for k in sorted(every)]
        tables = [table for table in (self._read_or_set_aside(p) for p in paths) if table is not None and table.num_rows]
        if not tables:
            return pd.DataFrame({"run_id": pd.Series(dtype=object), "seed": pd.Series(dtype="int64"), ERROR_COLUMN: pd.Series(dtype=object)})
        frame = pa.concat_tables(tables, promote_options="permissive").to_pandas()
        if ERROR_COLUMN not in frame:
            frame[ERROR_COLUMN] = None
        frame[ERROR_COLUMN] = frame[ERROR_COLUMN].astype(object).where(frame[ERROR_COLUMN].notna(), None)
        return frame


    def _read_or_set_aside(self, path: Path) -> pa.Table | None:
        """One store file, or ``None`` after setting it aside when it cannot be read."""
        try:
            return read_parquet(path)
        except (OSError, pa.ArrowException) as exc:
            self.set_aside(path, f"unreadable: {type(exc).__name__}")
            return None


def conform(table: pa.Table, schema: pa.Schema) -> pa.Table:
    """``table`` with exactly the columns of ``schema``, in its order (null where missing)."""
    columns = [table.column(f.name).cast(f.type) if f.name in table.column_names else pa.nulls(table.num_rows, f.type)
               for f in schema]
    return pa.Table.from_arrays(columns, schema=schema)


class StoreBusyError(ConfigError):
    """Another process is writing to this result store."""


class DamagedRunWarning(UserWarning):
    """A store file was damaged (e.g. truncated by a crash) and set aside; its run is redone."""


PARQUET_MAGIC = b"PAR1"


def has_parquet_magic(path: Path) -> bool:
    """Whether ``path`` starts and ends with the Parquet magic bytes (cheap completeness check)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(4)
            handle.seek(-4, os.SEEK_END)
            return head == PARQUET_MAGIC and handle.read(4) == PARQUET_MAGIC
    except OSError:
        return False


def read_parquet(path: Path) -> pa.Table:
    """One store file (``ParquetFile.read`` is about twice as fast as ``read_table`` here)."""
    with pq.ParquetFile(path) as handle:
        return handle.read()


def rows_to_table(rows: list[dict[str, Any]]) -> pa.Table:
    """An Arrow table from row dicts; a column mixing incompatible types becomes text."""
    columns: dict[str, list] = {}
    for row in rows:
        for key in row:
            columns.setdefault(key, [])
    for key, values in columns.items():
        values.extend(row.get(key) for row in rows)
    arrays = {}
    for key, values in columns.items():
        try:
            arrays[key] = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError, TypeError, OverflowError):
            arrays[key] = pa.array([None if v is None else str(v) for v in values], type=pa.string())
    return pa.table(arrays)


def empty_table(fields: Mapping[str, Any]) -> pa.Table:
    """A table with no rows whose columns are the task's fields."""
    return pa.table({k: pa.array([], type=pa.array([v]).type) for k, v in fields.items()})


def deterministic_columns(frame: pd.DataFrame) -> list[str]:
    """The columns of ``frame`` that must be equal for equal seeds (timings left out)."""
    return [c for c in frame.columns if not str(c).endswith(TIMING_SUFFIX)]


def check_tasks(tasks: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Validate task dicts (unique string ``run_id``, integer ``seed``); return copies."""
    out: list[dict[str, Any]] = []
    seen: set[str] = set()
    for index, task in enumerate(tasks):
        where = f"tasks[{index}]"
        if not isinstance(task, Mapping):
            raise ConfigError(f"{where}: expected a dict with run_id and seed, received {type(task).__name__}")
        run_id = check_run_id(task.get("run_id"), where)
        seed = task.get("seed")
        if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ConfigError(f"{where}: seed: expected a non-negative integer, received {seed!r}")
        if ERROR_COLUMN in task:
            raise ConfigError(f"{where}: {ERROR_COLUMN}: expected no such key (the column is reserved for failures), received one")
        if run_id in seen:
            raise ConfigError(f"{where}: run_id: expected a unique id, received the duplicate {run_id!r}")
        seen.add(run_id)
        out.append({str(k): v for k, v in task.items()})
    return out
