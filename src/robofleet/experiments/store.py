"""The result store: a directory holding a Parquet dataset of finished (and failed) tasks.

Layout (store format 2)
-----------------------
``<store>/batch-<n>.parquet``
    The records of many tasks, written together (``n`` counts up, six digits). A task's
    record is its rows, each with the task's fields merged in and ``error`` empty, or, for
    a task that raised, one row of its fields with ``error``, the one-line message. The
    file's Parquet metadata holds the store format and the ids of finished tasks that
    produced no rows. Its columns are in :func:`column_order`.
``<store>/.journal-<n>.jsonl``
    The records of the batch being collected, one JSON line per task, appended as each
    task finishes. When the batch is written (every :data:`BATCH_SECONDS`, every
    :data:`BATCH_CELLS` cells, and when the call ends or is interrupted) its journal is
    deleted; a journal left by a killed process is turned into ``batch-<n>.parquet`` by
    the next writer (or dropped if that batch is already there), so a kill loses only the
    tasks that were running. A line cut short by the kill is ignored.
``<store>/run-<id>.parquet``, ``<store>/error-<id>.parquet``
    A single task's record in a file of its own (:meth:`ResultStore.write_rows`,
    :meth:`ResultStore.write_error`): the layout of format 1, where every task had its
    own file. Stores of format 1 read and resume as they are. ``<id>`` is the
    percent-encoded ``run_id`` (:func:`file_stem`), so their ids are read from the
    listing alone.
``<store>/.<name>.tmp-<pid>-<hex>.parquet``
    A file being written. Every Parquet file is written under such a hidden name and
    then renamed with :func:`os.replace`, which is atomic on POSIX and Windows
    (:func:`robofleet.core.files.replacing`), so a process killed mid-write leaves either
    the complete file or only a hidden temporary that readers ignore (Parquet readers
    skip names starting with ``.`` or ``_``).
``<store>/_damaged/``
    Files found damaged (truncated by a crash, or not Parquet at all), set aside with one
    warning each; their tasks count as not finished and run again.

Every Parquet file is fsynced before the rename and the directory after it; the journal
is fsynced at least every :data:`JOURNAL_SYNC_SECONDS` (a killed process loses nothing
it appended; a machine that loses power, at most that last second).

Which record counts: a task is *finished* when any record of it finished (records of one
finished task are the same, whichever file holds them); otherwise its latest failure
(highest ``n``) is its record. Failed tasks count as *not finished*: the next run of the
same tasks retries them, and once they finish, the earlier failure rows are removed from
their files (:meth:`ResultStore.tidy`). A store file written in a later format is refused
with one line naming its format. The store has one writer at a time (the process driving
the sweep, holding ``<store>/.writer.lock``); a second sweep on the same directory is
refused with one line; workers only compute.

Columns whose name ends in ``_seconds`` are wall-clock timings: they differ between two
runs of the same seed, and :func:`deterministic_columns` leaves them out.
"""

from __future__ import annotations

import errno
import json
import os
import re
import threading
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping
from urllib.parse import quote, unquote

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

try:
    import fcntl
except ImportError:  # Windows: no advisory locks, the store then assumes one writer
    fcntl = None

from ..core import arguments
from ..core.errors import ConfigError
from ..core.files import is_temporary, replacing, sync_directory
from ..core.trace import to_plain

FORMAT = 2
"""The store format this module writes (and the latest it reads)."""
RUN_PREFIX = "run-"
ERROR_PREFIX = "error-"
BATCH_PREFIX = "batch-"
JOURNAL_PREFIX = ".journal-"
JOURNAL_SUFFIX = ".jsonl"
SUFFIX = ".parquet"
ERROR_COLUMN = "error"
TIMING_SUFFIX = "_seconds"
MAX_NAME_LENGTH = 240  # most file systems allow 255 bytes per name
DAMAGED_FOLDER = "_damaged"
LOCK_NAME = ".writer.lock"
META_FORMAT = b"robofleet.store.format"
META_WITHOUT_ROWS = b"robofleet.store.finished_without_rows"
BATCH_SECONDS = 300.0
"""A batch is written once its first record is this old (its journal holds it meanwhile)."""
BATCH_CELLS = 2_000_000
"""... or once its rows hold this many cells (bounds the writer's memory)."""
JOURNAL_SYNC_SECONDS = 1.0
"""The journal is fsynced at least this often while records are appended."""
_writing: set[str] = set()  # the stores this process holds the writer lock of
_writing_lock = threading.Lock()
BATCH_NAME = re.compile(rf"{BATCH_PREFIX}(\d+){re.escape(SUFFIX)}")
JOURNAL_NAME = re.compile(rf"{re.escape(JOURNAL_PREFIX)}(\d+){re.escape(JOURNAL_SUFFIX)}")


def file_stem(run_id: str) -> str:
    """The file-name-safe encoding of ``run_id`` (inverse: :func:`urllib.parse.unquote`)."""
    return quote(run_id, safe="")


SHORT_RUN_ID = (MAX_NAME_LENGTH - len(ERROR_PREFIX + SUFFIX)) // 12
"""Run ids this long or shorter name a file whatever their characters (a character
percent-encodes to at most 12 bytes)."""


def check_run_id(run_id: Any, where: str = "task") -> str:
    """Return ``run_id`` if it is a non-empty string short enough to name a file."""
    if not isinstance(run_id, str) or not run_id:
        raise ConfigError(f"{where}: run_id: expected a non-empty string, received {run_id!r}")
    if len(run_id) > SHORT_RUN_ID and len(ERROR_PREFIX + file_stem(run_id) + SUFFIX) > MAX_NAME_LENGTH:
        raise ConfigError(f"{where}: run_id: expected at most ~200 characters once percent-encoded, received {len(run_id)} characters")
    return run_id


PLAIN_CELL_TYPES = frozenset({type(None), bool, int, float, str})


def cell_value(value: Any) -> Any:
    """A Parquet- and JSON-friendly scalar: ``None``, a bool, an int, a float or a string.

    Numpy scalars become Python; lists and dicts become JSON text; anything else its
    ``str``. Every cell has one of these JSON-native types, so a record read back from a
    journal is the record that was written (:meth:`Record.from_line`).
    """
    if type(value) in PLAIN_CELL_TYPES:  # the common case, decided without conversions
        return value
    value = to_plain(value)
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, dict)):
        return json.dumps(to_plain(value, json_safe=True), sort_keys=True, allow_nan=False)
    return str(value)


@dataclass
class Record:
    """What the store keeps of one task: its fields and its rows, or its error message.

    ``fields`` are the task's fields as cells; ``rows`` the task function's rows as cells,
    without the keys the fields already have (the task's fields win); ``error`` is
    ``None`` for a finished task.
    """

    fields: dict[str, Any]
    rows: list[dict[str, Any]] = field(default_factory=list)
    error: str | None = None

    @property
    def run_id(self) -> str:
        return str(self.fields["run_id"])

    @property
    def finished(self) -> bool:
        return self.error is None

    @classmethod
    def of(cls, task: Mapping[str, Any], status: str, payload: Any) -> Record:
        """The record of an executor outcome: ``("ok", rows)`` or ``("error", message)``."""
        fields = {str(k): cell_value(v) for k, v in task.items()}
        if status != "ok":
            return cls(fields, [], str(payload))
        rows = [{str(k): cell_value(v) for k, v in row.items() if k not in fields} for row in payload]
        return cls(fields, rows)

    def table_rows(self) -> list[dict[str, Any]]:
        """The rows this record puts in the table (none for a finished task without rows)."""
        if not self.finished:
            return [{**self.fields, ERROR_COLUMN: self.error}]
        return [{**self.fields, **row, ERROR_COLUMN: None} for row in self.rows]

    def line(self) -> str:
        """One journal line (JSON, newline-terminated)."""
        return json.dumps({"fields": self.fields, "rows": self.rows, "error": self.error}, allow_nan=True) + "\n"

    @classmethod
    def from_line(cls, line: str) -> Record | None:
        """The record of a complete journal line, or ``None`` for a line cut short."""
        if not line.endswith("\n"):
            return None
        try:
            data = json.loads(line)
            return cls(dict(data["fields"]), [dict(r) for r in data["rows"]], data["error"])
        except (ValueError, KeyError, TypeError):
            return None


class ResultStore:
    """A directory of Parquet files of task records (see the module docstring).

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
    def _listing(self) -> Listing:
        return Listing.of(self.directory)

    def finished_ids(self) -> set[str]:
        """Run ids whose task finished without error (these are skipped on re-runs)."""
        return self._contents().finished

    def failed_ids(self) -> set[str]:
        """Run ids whose last attempt raised and that have not finished since."""
        contents = self._contents()
        return contents.failed - contents.finished

    def _contents(self) -> Contents:
        """Which tasks every file holds (a file renamed away while being read: read again)."""
        for _ in range(5):
            try:
                return Contents.of(self._listing(), self)
            except FileNotFoundError:
                continue
        return Contents.of(self._listing(), self)

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
        """Store the rows of one finished task in a file of its own (``run-<id>.parquet``),
        each merged with the task's fields.

        The task's fields come first and win over a row key of the same name. A task
        that produced no rows is still recorded (a file with no rows), so it is not rerun.
        :func:`~robofleet.experiments.run_tasks` writes many tasks per file instead
        (:meth:`batches`).
        """
        record = Record.of(task, "ok", rows)
        path = self._write_records(RUN_PREFIX + file_stem(record.run_id) + SUFFIX, [record])
        (self.directory / (ERROR_PREFIX + file_stem(record.run_id) + SUFFIX)).unlink(missing_ok=True)
        return path

    def write_error(self, task: Mapping[str, Any], message: str) -> Path:
        """Store one row for a task that raised, in a file of its own: its fields plus
        ``error = message``."""
        record = Record.of(task, "error", message)
        return self._write_records(ERROR_PREFIX + file_stem(record.run_id) + SUFFIX, [record])

    def _write_records(self, name: str, records: list[Record]) -> Path:
        return self._atomic_write(name, records_table(records))

    def _atomic_write(self, name: str, table: pa.Table) -> Path:
        """Write one store file through :func:`~robofleet.core.files.replacing`: after a
        crash it is either complete or absent."""
        with replacing(self.directory / name) as temp:
            pq.write_table(table, temp)
        return self.directory / name

    @contextmanager
    def batches(self) -> Iterator[BatchWriter]:
        """A :class:`BatchWriter` appending to this store; what it holds is written when
        the block ends, normally or by an exception (``KeyboardInterrupt`` included).
        Call it only from the store's writer (:meth:`writer_lock`), after :meth:`recover`."""
        writer = BatchWriter(self, self._listing().next_number())
        try:
            yield writer
        finally:
            writer.close()

    def recover(self) -> None:
        """Make the store whole after a killed writer: delete temporaries, set damaged
        files aside, and turn every journal into its batch file (or drop it, if that batch
        is already written). Call it only from the store's writer."""
        self.remove_temporaries()
        self.set_aside_damaged()
        listing = self._listing()
        for number, journal in sorted(listing.journals.items()):
            if number not in listing.batches:
                records = read_journal(journal)
                if records:
                    self._write_records(batch_name(number), records)
            journal.unlink(missing_ok=True)

    def tidy(self) -> int:
        """Remove the failure rows of tasks that have finished since (or failed again
        later), then give every file the same columns (:meth:`unify_columns`). Afterwards
        any Parquet reader sees one record per task. Returns how many files changed.
        Call it only from the store's writer."""
        contents = self._contents()
        changed = 0
        for run_id, path in list(self._listing().errors.items()):
            if run_id in contents.finished or contents.latest_failure.get(run_id, 0) > 0:
                path.unlink(missing_ok=True)
                changed += 1
        for number, path in self._listing().batches.items():
            stale = contents.stale_failures(number)
            if stale:
                table = read_store_table(path)
                keep = pc.invert(pc.and_(pc.is_in(table["run_id"], pa.array(sorted(stale), pa.string())), pc.is_valid(table[ERROR_COLUMN])))
                self._atomic_write(path.name, table.filter(keep).replace_schema_metadata(table.schema.metadata))
                changed += 1
        return changed + self.unify_columns()

    # -- one writer --------------------------------------------------------------
    @contextmanager
    def writer_lock(self) -> Iterator[None]:
        """Hold the store's writer lock (``<store>/.writer.lock``) for the duration of the block.

        The lock is a POSIX record lock (``lockf``), which the OS releases when the process
        dies and which worker processes forked meanwhile do not inherit (an ``flock`` they
        would: a killed sweep's orphaned workers would keep its store locked), plus a
        record of the stores this process is writing (record locks do not exclude the
        process holding them).

        Raises
        ------
        StoreBusyError
            If another sweep holds it: a second sweep on the same directory is refused
            rather than racing the first one. (Where ``fcntl`` is missing, e.g. Windows,
            only sweeps of this process are excluded.)
        """
        self.directory.mkdir(parents=True, exist_ok=True)
        key = os.path.realpath(self.directory)
        with _writing_lock:
            if key in _writing:
                raise self._busy(str(os.getpid()))
            _writing.add(key)
        try:
            with open(self.directory / LOCK_NAME, "a+") as handle:
                if fcntl is not None:
                    try:
                        fcntl.lockf(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
                    except OSError as exc:
                        if exc.errno not in (errno.EACCES, errno.EAGAIN):
                            raise
                        handle.seek(0)
                        raise self._busy(handle.read().strip() or "?") from None
                handle.seek(0)
                handle.truncate()
                handle.write(str(os.getpid()))
                handle.flush()
                yield
        finally:
            with _writing_lock:
                _writing.discard(key)

    def _busy(self, holder: str) -> StoreBusyError:
        return StoreBusyError(f"store: expected a store no other sweep is writing to, received {self.directory}, "
                              f"which process {holder} is writing; wait for it or choose another --out")

    # -- one schema --------------------------------------------------------------
    def unify_columns(self) -> int:
        """Give every store file the same columns, types and column order (the union of
        all files', in :func:`column_order`, with nulls where a file lacks a column), so
        that ``pandas.read_parquet(store)`` and ``polars.read_parquet(store / "*.parquet")``
        read every row. Rewrites only the files that differ; returns how many were
        rewritten. Call it only from the store's writer.
        """
        paths = self._listing().parquet_files()
        schemas = {path: pq.read_schema(path) for path in paths}
        if len({schema.remove_metadata() for schema in schemas.values()}) <= 1:
            return 0
        unified = unified_schema(schemas)
        rewritten = 0
        for path, schema in schemas.items():
            if not schema.remove_metadata().equals(unified):
                table = read_store_table(path)
                self._atomic_write(path.name, conform(table, unified).replace_schema_metadata(table.schema.metadata))
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
        return [self.set_aside(path, "not a complete Parquet file")
                for path in self._listing().parquet_files() if not has_parquet_magic(path)]

    # -- reading -----------------------------------------------------------------
    def read(self) -> pd.DataFrame:
        """Every stored row (finished and failed tasks, one record per task), ordered by
        ``run_id`` (a task's rows in their order), columns in :func:`column_order`.

        The frame always has the columns ``run_id``, ``seed`` and ``error`` (``None`` on
        rows of tasks that finished). The rows of a journal a killed writer left are
        included.
        """
        for _ in range(5):
            try:
                return self._read()
            except FileNotFoundError:  # a journal became a batch while being read
                continue
        return self._read()

    def _read(self) -> pd.DataFrame:
        listing = self._listing()
        sources = [source for source in (self._source(order, path) for order, path in listing.ordered()) if source is not None]
        chosen = choose_records(sources)
        tables = [source.table.filter(mask) if mask is not None else source.table for source, mask in zip(sources, chosen)]
        tables = [table for table in tables if table.num_rows]
        if not tables:
            return pd.DataFrame({"run_id": pd.Series(dtype=object), "seed": pd.Series(dtype="int64"), ERROR_COLUMN: pd.Series(dtype=object)})
        schema = unified_schema({source.path: source.table.schema for source in sources if source.table.num_rows})
        table = pa.concat_tables([conform(t, schema) for t in tables])
        table = table.take(pc.sort_indices(table, sort_keys=[("run_id", "ascending")]))  # stable: a task's rows keep their order
        frame = table.to_pandas()
        frame[ERROR_COLUMN] = frame[ERROR_COLUMN].astype(object).where(frame[ERROR_COLUMN].notna(), None)
        return frame

    def _source(self, order: tuple, path: Path) -> Source | None:
        """One file's records, or ``None`` after setting a damaged file aside."""
        if path.name.startswith(JOURNAL_PREFIX):
            records = read_journal(path)
            return Source(order, path, records_table(records), {r.run_id for r in records if r.finished and not r.rows})
        try:
            table = read_store_table(path)
        except (OSError, pa.ArrowException) as exc:
            if isinstance(exc, FileNotFoundError):
                raise
            self.set_aside(path, f"unreadable: {type(exc).__name__}")
            return None
        return Source(order, path, table, finished_without_rows(table, path))


# -- the files of a store ------------------------------------------------------------
def batch_name(number: int) -> str:
    return f"{BATCH_PREFIX}{number:06d}{SUFFIX}"


def journal_name(number: int) -> str:
    return f"{JOURNAL_PREFIX}{number:06d}{JOURNAL_SUFFIX}"


@dataclass
class Listing:
    """The store files of a directory, by kind (one directory scan)."""

    runs: dict[str, Path]
    errors: dict[str, Path]
    batches: dict[int, Path]
    journals: dict[int, Path]

    @classmethod
    def of(cls, directory: Path) -> Listing:
        listing = cls({}, {}, {}, {})
        if not directory.is_dir():
            return listing
        for entry in os.scandir(directory):
            name = entry.name
            if is_temporary(name) or not entry.is_file():
                continue
            if match := BATCH_NAME.fullmatch(name):
                listing.batches[int(match.group(1))] = Path(entry.path)
            elif match := JOURNAL_NAME.fullmatch(name):
                listing.journals[int(match.group(1))] = Path(entry.path)
            elif name.endswith(SUFFIX) and name.startswith(RUN_PREFIX):
                listing.runs[unquote(name[len(RUN_PREFIX):-len(SUFFIX)])] = Path(entry.path)
            elif name.endswith(SUFFIX) and name.startswith(ERROR_PREFIX):
                listing.errors[unquote(name[len(ERROR_PREFIX):-len(SUFFIX)])] = Path(entry.path)
        return listing

    def parquet_files(self) -> list[Path]:
        return [*self.runs.values(), *self.errors.values(), *self.batches.values()]

    def next_number(self) -> int:
        return max([0, *self.batches, *self.journals]) + 1

    def ordered(self) -> list[tuple[tuple, Path]]:
        """Every file with its place in time: single-task files (format 1) first, then
        batches and journals by number (a batch and the journal it came from are the same
        records; the batch comes first)."""
        single = [((0, 0, name), path) for name, path in sorted((p.name, p) for p in [*self.runs.values(), *self.errors.values()])]
        numbered = [((1, n, 0), p) for n, p in self.batches.items()] + [((1, n, 1), p) for n, p in self.journals.items()]
        return single + sorted(numbered)


@dataclass
class Source:
    """The records of one store file (or journal)."""

    order: tuple
    path: Path
    table: pa.Table
    without_rows: set[str]

    def ids(self) -> tuple[set[str], set[str]]:
        """``(finished, failed)`` run ids in this file."""
        finished, failed = set(self.without_rows), set()
        if self.table.num_rows:
            ids, errors = self.table["run_id"], self.table[ERROR_COLUMN] if ERROR_COLUMN in self.table.column_names else None
            if errors is None:
                finished.update(pc.unique(ids).to_pylist())
            else:
                finished.update(pc.unique(ids.filter(pc.is_null(errors))).to_pylist())
                failed.update(pc.unique(ids.filter(pc.is_valid(errors))).to_pylist())
        return finished, failed


@dataclass
class Contents:
    """Which tasks the store holds: finished and failed ids, and where failures are."""

    finished: set[str]
    failed: set[str]
    failures: dict[int, set[str]]  # batch number -> failed ids in it
    latest_failure: dict[str, int]

    @classmethod
    def of(cls, listing: Listing, store: ResultStore) -> Contents:
        finished, failed = set(listing.runs), set(listing.errors)
        failures: dict[int, set[str]] = {}
        latest: dict[str, int] = {run_id: 0 for run_id in listing.errors}
        for (kind, number, _), path in listing.ordered():
            if kind == 0:
                continue
            if path.name.startswith(JOURNAL_PREFIX):
                records = read_journal(path)
                done = {r.run_id for r in records if r.finished}
                bad = {r.run_id for r in records if not r.finished}
            else:
                table = read_store_table(path, columns=["run_id", ERROR_COLUMN])
                done, bad = Source((), path, table, finished_without_rows(table, path)).ids()
                failures[number] = bad
            finished |= done
            failed |= bad
            latest.update(dict.fromkeys(bad, number))
        return cls(finished, failed, failures, latest)

    def stale_failures(self, number: int) -> set[str]:
        """Failure rows of batch ``number`` that no longer count (finished, or failed later)."""
        return {run_id for run_id in self.failures.get(number, ())
                if run_id in self.finished or self.latest_failure.get(run_id, number) > number}


def choose_records(sources: list[Source]) -> list[pa.Array | None]:
    """Per source, the mask of rows that count (``None``: all of them): a finished task's
    rows from the first file holding them, else its latest failure."""
    ids = [source.ids() for source in sources]
    owner_finished: dict[str, int] = {}
    owner_failed: dict[str, int] = {}
    for index, (finished, failed) in enumerate(ids):
        for run_id in finished:
            owner_finished.setdefault(run_id, index)
        for run_id in failed:
            owner_failed[run_id] = index
    masks: list[pa.Array | None] = []
    for index, (source, (finished, failed)) in enumerate(zip(sources, ids)):
        drop = {r for r in finished if owner_finished[r] != index}
        drop |= {r for r in failed if r in owner_finished or owner_failed[r] != index}
        if not drop or not source.table.num_rows:
            masks.append(None)
            continue
        is_error = pc.is_valid(source.table[ERROR_COLUMN]) if ERROR_COLUMN in source.table.column_names else pa.repeat(False, source.table.num_rows)
        dropped_ok = pc.and_(pc.is_in(source.table["run_id"], pa.array(sorted(r for r in drop if r in finished), pa.string())), pc.invert(is_error))
        dropped_bad = pc.and_(pc.is_in(source.table["run_id"], pa.array(sorted(r for r in drop if r in failed), pa.string())), is_error)
        masks.append(pc.invert(pc.or_(dropped_ok, dropped_bad)))
    return masks


# -- batches ----------------------------------------------------------------------
class BatchWriter:
    """Collects task records and writes them many per file (see the module docstring).

    Each record is appended to the batch's journal as it is added (one ``os.write`` per
    call), so a process killed at any moment loses none of them; the batch becomes
    ``batch-<n>.parquet`` after :data:`BATCH_SECONDS` or :data:`BATCH_CELLS`, and when
    the writer is closed.
    """

    def __init__(self, store: ResultStore, number: int):
        self.store = store
        self.number = number
        self.records: list[Record] = []
        self.cells = 0
        self.journal: int | None = None  # file descriptor
        self.opened = self.synced = 0.0

    def add(self, results: Iterable[tuple[Mapping[str, Any], tuple[str, Any]]]) -> None:
        """Record executor results ``(task, (status, payload))``."""
        records = [Record.of(task, status, payload) for task, (status, payload) in results]
        if not records:
            return
        self.records.extend(records)  # first kept here: an interrupt after this is still written by close()
        self.cells += sum(max(1, len(r.rows)) * (len(r.fields) + (len(r.rows[0]) if r.rows else 1)) for r in records)
        if self.journal is None:
            self.store.directory.mkdir(parents=True, exist_ok=True)
            path = self.store.directory / journal_name(self.number)
            self.journal = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_TRUNC, 0o644)
            sync_directory(self.store.directory)
            self.opened = self.synced = time.monotonic()
        os.write(self.journal, "".join(r.line() for r in records).encode())
        now = time.monotonic()
        if self.cells >= BATCH_CELLS or now - self.opened >= BATCH_SECONDS:
            self.flush()
        elif now - self.synced >= JOURNAL_SYNC_SECONDS:
            os.fsync(self.journal)
            self.synced = now

    def flush(self) -> None:
        """Write the records collected so far as ``batch-<n>.parquet``, then drop their journal."""
        if self.journal is None:
            return
        if self.records:
            self.store._write_records(batch_name(self.number), self.records)
        os.close(self.journal)
        self.journal = None
        (self.store.directory / journal_name(self.number)).unlink(missing_ok=True)
        self.number += 1
        self.records, self.cells = [], 0

    def close(self) -> None:
        self.flush()


def read_journal(path: Path) -> list[Record]:
    """The complete records of a journal (a line a kill cut short is left out)."""
    with open(path, encoding="utf-8") as handle:
        records = [Record.from_line(line) for line in handle]
    return [r for r in records if r is not None]


def records_table(records: list[Record]) -> pa.Table:
    """The Parquet table of some records: rows in ``run_id`` order, columns in
    :func:`column_order`, an ``error`` column always (text), and the metadata of a batch
    (format, finished tasks without rows)."""
    ordered = sorted(records, key=lambda r: r.run_id)
    rows = [row for record in ordered for row in record.table_rows()]
    fields = ordered[0].fields if ordered else {"run_id": "", "seed": 0}
    table = rows_to_table(rows) if rows else empty_table({**fields, ERROR_COLUMN: ""})
    table = table.set_column(table.schema.get_field_index(ERROR_COLUMN), ERROR_COLUMN, table[ERROR_COLUMN].cast(pa.string()))
    metadata = {META_FORMAT: str(FORMAT).encode(),
                META_WITHOUT_ROWS: json.dumps(sorted(r.run_id for r in ordered if r.finished and not r.rows)).encode()}
    return table.select(column_order(table.column_names)).replace_schema_metadata(metadata)


def finished_without_rows(table: pa.Table, path: Path) -> set[str]:
    """The finished tasks without rows a store file records (after checking its format)."""
    metadata = table.schema.metadata or {}
    check_format(metadata, path)
    if META_WITHOUT_ROWS in metadata:
        return set(json.loads(metadata[META_WITHOUT_ROWS]))
    if path.name.startswith(RUN_PREFIX) and not table.num_rows:  # format 1: a task without rows has an empty file
        return {unquote(path.name[len(RUN_PREFIX):-len(SUFFIX)])}
    return set()


def check_format(metadata: Mapping[bytes, bytes], path: Path) -> None:
    """Refuse a file written in a later store format, in one line naming it."""
    written = metadata.get(META_FORMAT, b"1")
    try:
        version = int(written)
    except ValueError:
        version = None
    if version is None or version > FORMAT:
        raise StoreFormatError(f"store: expected result store files of format {FORMAT} or earlier, received {path} "
                               f"of format {written.decode(errors='replace')} (written by a later robofleet; upgrade to read it)")


def column_order(names: Iterable[str]) -> list[str]:
    """The columns of a store in one order that does not depend on how its tasks were
    grouped into files or in which order they finished: ``run_id`` and ``seed``, the
    others by name, ``error`` last."""
    names = set(names)
    first = [name for name in ("run_id", "seed") if name in names]
    return first + sorted(names - {*first, ERROR_COLUMN}) + ([ERROR_COLUMN] if ERROR_COLUMN in names else [])


def unified_schema(schemas: Mapping[Path, pa.Schema]) -> pa.Schema:
    """One schema for several store files: every column (``error`` always), types promoted, in :func:`column_order`."""
    merged = pa.unify_schemas([s.remove_metadata() for s in schemas.values()]
                              + [pa.schema([(ERROR_COLUMN, pa.string())])], promote_options="permissive")
    return pa.schema([merged.field(name) for name in column_order(merged.names)])


def conform(table: pa.Table, schema: pa.Schema) -> pa.Table:
    """``table`` with exactly the columns of ``schema``, in its order (null where missing)."""
    columns = [table.column(f.name).cast(f.type) if f.name in table.column_names else pa.nulls(table.num_rows, f.type)
               for f in schema]
    return pa.Table.from_arrays(columns, schema=schema)


class StoreBusyError(ConfigError):
    """Another process is writing to this result store."""


class StoreFormatError(ConfigError):
    """A store file was written in a later store format than this robofleet reads."""


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


def read_parquet(path: Path, columns: list[str] | None = None) -> pa.Table:
    """One store file (``ParquetFile.read`` is about twice as fast as ``read_table`` on
    small files); ``columns`` that the file lacks are left out."""
    with pq.ParquetFile(path) as handle:
        if columns is not None:
            columns = [c for c in columns if c in handle.schema_arrow.names]
        return handle.read(columns=columns)


def read_store_table(path: Path, columns: list[str] | None = None) -> pa.Table:
    """One store file with its metadata, refused in one line if written in a later format."""
    table = read_parquet(path, columns)
    check_format(table.schema.metadata or {}, path)
    return table


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
        if type(task) is not dict and not isinstance(task, Mapping):
            raise ConfigError(f"{where}: expected a dict with run_id and seed, received {type(task).__name__}")
        run_id = check_run_id(task.get("run_id"), where)
        seed = task.get("seed")
        if type(seed) is not int and (isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer))) or seed < 0:
            raise ConfigError(f"{where}: seed: expected a non-negative integer, received {seed!r}")
        if ERROR_COLUMN in task:
            raise ConfigError(f"{where}: {ERROR_COLUMN}: expected no such key (the column is reserved for failures), received one")
        if run_id in seen:
            raise ConfigError(f"{where}: run_id: expected a unique id, received the duplicate {run_id!r}")
        seen.add(run_id)
        out.append({str(k): v for k, v in task.items()})
    return out
