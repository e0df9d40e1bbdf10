"""A run's events as columns: :class:`Events` (what a trace holds) and :class:`EventLog`
(what the recorder appends to while the run goes).

An event is ``{"step": 12, "kind": "deadlock", "robot": 3, ...}``. A run with thousands
of robots records millions of them, so they are kept as columns, one value per event:

* ``step`` (integers) and ``kind`` (a code into the table :attr:`Events.kinds`);
* one :class:`Column` per other field, of one *column kind*: ``integer``, ``number``,
  ``boolean``, ``string`` (a code into a table of texts), ``list of integer``, ``list of
  number``, ``list of boolean`` (the items of all events in one array, with offsets), or
  ``json`` (anything else: each value as JSON text, a code into a table of texts); a
  column that not every event has carries a ``present`` mask.

Read one event at a time, the table is the list of dicts it stands for (``events[i]``,
iteration, ``==`` with a list of dicts), with integers read back as ``int``, numbers as
``float``: ``Events.from_records(rows) == rows`` for rows of plain JSON values. Large
runs are read by column instead (:meth:`Events.column`, :attr:`Events.steps`,
:meth:`Events.kind_mask`), without making a dict per event.

Saved, the columns are arrays of ``trace.npz`` named ``events.step``, ``events.kind``,
``events.<field>`` (and ``events.<field>:present``, ``events.<field>:offsets``), and
``trace.json`` holds their description (:meth:`Events.describe`): the count, the kind
table, each field's column kind and text table.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import ConfigError, short_repr

PREFIX = "events."
"""Names of the event columns in ``trace.npz`` start with this."""
PRESENT, OFFSETS = ":present", ":offsets"
SCALAR_KINDS = {"integer": np.int64, "number": np.float64, "boolean": np.bool_}
LIST_KINDS = {f"list of {k}": dtype for k, dtype in SCALAR_KINDS.items()}
TEXT_KINDS = ("string", "json")
COLUMN_KINDS = (*SCALAR_KINDS, *LIST_KINDS, *TEXT_KINDS)
"""Every column kind (see the module docstring)."""
RESERVED = ("step", "kind")


def plain(value: Any) -> Any:
    """A numpy scalar or array as plain Python (other values as they are)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def value_kind(value: Any) -> str:
    """The kind of one plain value: a scalar kind, ``list of K``, ``list`` (empty) or ``json``."""
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer" if -2**63 <= value < 2**63 else "json"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, (list, tuple)):
        if not value:
            return "list"
        items = {value_kind(v) for v in value}
        kind = merge_kinds(items) if items <= set(SCALAR_KINDS) else "json"
        return f"list of {kind}" if kind in SCALAR_KINDS else "json"
    return "json"


def merge_kinds(kinds: Iterable[str]) -> str:
    """The column kind holding values of all ``kinds``: the one kind, ``number`` for
    integers and numbers (as items of lists too; an empty list fits any list), else ``json``."""
    found = set(kinds)
    if "list" in found and len(found) > 1:
        found.discard("list")
    if found == {"list"}:
        return "list of integer"
    if len(found) == 1:
        return found.pop()
    if found == {"integer", "number"}:
        return "number"
    if found == {"list of integer", "list of number"}:
        return "list of number"
    return "json"


def json_safe(value: Any) -> Any:
    """``value`` with numpy values as plain Python, tuples as lists, dict keys as strings
    and non-finite numbers as ``None`` (recursively)."""
    value = plain(value)
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def json_text(value: Any) -> str:
    """Strict JSON text of one value (non-finite numbers as ``null``)."""
    return json.dumps(json_safe(value), separators=(",", ":"), allow_nan=False)


@dataclass(frozen=True)
class Column:
    """One field of every event (see the module docstring).

    ``values``: one per event (scalars; codes into ``labels`` for ``string`` and ``json``),
    or the items of every event's list (``list of K``, event ``i`` holding
    ``values[offsets[i]:offsets[i+1]]``); ``present``: which events have the field
    (``None``: all of them)."""

    kind: str
    values: np.ndarray
    present: np.ndarray | None = None
    offsets: np.ndarray | None = None
    labels: tuple[str, ...] = ()

    def has(self, index: int) -> bool:
        return self.present is None or bool(self.present[index])

    def value(self, index: int) -> Any:
        """The plain value of event ``index`` (which has the field)."""
        if self.offsets is not None:
            return self.values[self.offsets[index]:self.offsets[index + 1]].tolist()
        if self.kind == "string":
            return self.labels[self.values[index]]
        if self.kind == "json":
            return json.loads(self.labels[self.values[index]])
        return self.values[index].item()

    def mask(self, n: int) -> np.ndarray:
        return np.ones(n, bool) if self.present is None else self.present

    def take(self, index: np.ndarray) -> "Column":
        present = None if self.present is None else self.present[index]
        if self.offsets is None:
            return Column(self.kind, self.values[index], present, None, self.labels)
        starts, ends = self.offsets[index], self.offsets[index + 1]
        counts = ends - starts
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        items = np.repeat(starts - offsets[:-1], counts) + np.arange(offsets[-1])
        return Column(self.kind, self.values[items], present, offsets, self.labels)

    def as_kind(self, kind: str, n: int) -> "Column":
        """This column as one of column kind ``kind`` (a wider one, see :func:`merge_kinds`)."""
        if kind == self.kind:
            return self
        if kind in SCALAR_KINDS and self.kind in SCALAR_KINDS or kind in LIST_KINDS and self.kind in LIST_KINDS:
            dtype = SCALAR_KINDS.get(kind) or LIST_KINDS[kind]
            return Column(kind, self.values.astype(dtype), self.present, self.offsets, self.labels)
        texts = [json_text(self.value(i)) if self.has(i) else "null" for i in range(n)]
        return text_column("json", texts, self.present)


def text_column(kind: str, texts: Sequence[str], present: np.ndarray | None) -> Column:
    """A ``string`` or ``json`` column of one text per event (codes into their table)."""
    labels, codes = np.unique(np.asarray(texts, dtype=object).astype(str), return_inverse=True) if len(texts) else (np.array([], str), np.zeros(0, np.int64))
    return Column(kind, codes.astype(np.int32).reshape(-1), present, None, tuple(str(t) for t in labels))


def build_column(kind: str, values: list[Any], index: np.ndarray, n: int) -> Column:
    """The column of kind ``kind`` of events ``index`` (of ``n``) having ``values``."""
    present = None if len(index) == n else np.zeros(n, bool)
    if present is not None:
        present[index] = True
    if kind in SCALAR_KINDS:
        out = np.zeros(n, SCALAR_KINDS[kind])
        out[index] = values
        return Column(kind, out, present)
    if kind in LIST_KINDS:
        counts = np.zeros(n, np.int64)
        counts[index] = [len(v) for v in values]
        flat = [item for v in values for item in v]
        return Column(kind, np.array(flat, LIST_KINDS[kind]).reshape(-1), present, np.concatenate([[0], np.cumsum(counts)]))
    texts = ["null"] * n
    for i, v in zip(index.tolist(), values):
        texts[i] = v if kind == "string" else json_text(v)
    return text_column(kind, texts, present)


class Events(Sequence):
    """The events of a run as columns (see the module docstring).

    Attributes
    ----------
    steps: ``(n,)`` int64, the step of each event.
    codes: ``(n,)`` int32, each event's kind as an index into ``kinds``.
    kinds: the kind table.
    columns: field name → :class:`Column`, in the order fields first appeared.
    """

    def __init__(self, steps: np.ndarray, codes: np.ndarray, kinds: Sequence[str], columns: Mapping[str, Column] | None = None):
        self.steps = np.asarray(steps, np.int64).reshape(-1)
        self.codes = np.asarray(codes, np.int32).reshape(-1)
        self.kinds = tuple(kinds)
        self.columns = dict(columns or {})

    # -- building ------------------------------------------------------------------------
    @classmethod
    def empty(cls) -> "Events":
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int32), ())

    @classmethod
    def batch(cls, step: Any, kind: str, **fields: Any) -> "Events":
        """Events of one ``kind`` from arrays of equal length (scalars are repeated): e.g.
        ``Events.batch(12, "deadlock", robot=np.flatnonzero(mask))``."""
        arrays = {name: np.asarray(value) for name, value in fields.items()}
        sizes = [len(a) for a in arrays.values() if a.ndim] + ([np.size(step)] if np.ndim(step) else [])
        n = sizes[0] if sizes else 1
        columns = {}
        for name, a in arrays.items():
            kind_of_column = {"b": "boolean", "i": "integer", "u": "integer", "f": "number"}.get(a.dtype.kind)
            if kind_of_column is None or a.ndim > 1:
                raise ConfigError(f"event field {name!r}: expected numbers or booleans, one per event, received {short_repr(a)}")
            columns[name] = Column(kind_of_column, np.broadcast_to(a, (n,)).astype(SCALAR_KINDS[kind_of_column]))
        return cls(np.broadcast_to(np.asarray(step, np.int64), (n,)), np.zeros(n, np.int32), (kind,), columns)

    @classmethod
    def from_records(cls, rows: Iterable[Mapping[str, Any]]) -> "Events":
        """The table of a list of event dicts (each with an integer ``step`` and a string ``kind``).

        Raises
        ------
        ConfigError
            An event is not a mapping with ``step`` and ``kind``.
        """
        rows = list(rows)
        kinds: dict[str, int] = {}
        steps, codes = np.zeros(len(rows), np.int64), np.zeros(len(rows), np.int32)
        fields: dict[str, tuple[list[int], list[Any]]] = {}
        for i, row in enumerate(rows):
            step, kind = plain(row.get("step")) if isinstance(row, Mapping) else None, row.get("kind") if isinstance(row, Mapping) else None
            if not isinstance(step, int) or isinstance(step, bool) or not isinstance(kind, str) or not kind:
                raise ConfigError(f"events[{i}]: expected an event with an integer step and a kind, received {short_repr(row)}")
            steps[i], codes[i] = step, kinds.setdefault(kind, len(kinds))
            for name, value in row.items():
                if name not in RESERVED:
                    index, values = fields.setdefault(name, ([], []))
                    index.append(i)
                    values.append(plain(value))
        columns = {name: build_column(merge_kinds(value_kind(v) for v in values), values, np.asarray(index, np.int64), len(rows))
                   for name, (index, values) in fields.items()}
        return cls(steps, codes, tuple(kinds), columns)

    @classmethod
    def concat(cls, parts: Sequence["Events"]) -> "Events":
        """The events of ``parts`` one after the other (kind tables and columns merged)."""
        parts = [p for p in parts if len(p)]
        if len(parts) == 1:
            return parts[0]
        if not parts:
            return cls.empty()
        kinds: dict[str, int] = {}
        codes = []
        for p in parts:
            table = np.array([kinds.setdefault(k, len(kinds)) for k in p.kinds], np.int32)
            codes.append(table[p.codes] if len(table) else p.codes)
        names = list(dict.fromkeys(name for p in parts for name in p.columns))
        columns = {name: concat_columns([p.columns.get(name) for p in parts], [len(p) for p in parts]) for name in names}
        return cls(np.concatenate([p.steps for p in parts]), np.concatenate(codes), tuple(kinds), columns)

    @classmethod
    def from_arrays(cls, description: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> "Events":
        """The table of saved columns (``arrays`` named as :meth:`to_arrays` names them) and
        their description (:meth:`describe`), as they are: :meth:`Trace.load
        <robofleet.core.trace.Trace.load>` checks them first."""
        columns = {}
        for name, entry in description["fields"].items():
            columns[name] = Column(entry["kind"], np.asarray(arrays[PREFIX + name]), arrays.get(PREFIX + name + PRESENT),
                                   arrays.get(PREFIX + name + OFFSETS), tuple(entry.get("labels") or ()))
        return cls(arrays[PREFIX + "step"], arrays[PREFIX + "kind"], description["kinds"], columns)

    # -- reading -------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.steps)

    def record(self, index: int) -> dict[str, Any]:
        """Event ``index`` as a dict."""
        out = {"step": int(self.steps[index]), "kind": self.kinds[self.codes[index]]}
        for name, column in self.columns.items():
            if column.has(index):
                out[name] = column.value(index)
        return out

    def __getitem__(self, index):
        if isinstance(index, slice):
            return self.take(np.arange(len(self))[index])
        if isinstance(index, (int, np.integer)) and not isinstance(index, bool):
            if not -len(self) <= index < len(self):
                raise IndexError(f"event index {index} out of range for {len(self)} events")
            return self.record(int(index) % len(self))
        raise TypeError(f"events: expected an integer index or a slice, received {short_repr(index)}")

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return (self.record(i) for i in range(len(self)))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Events):
            return self.same_as(other)
        if isinstance(other, (list, tuple)):
            return len(other) == len(self) and all(a == b for a, b in zip(self, other))
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        counts = ", ".join(f"{k}: {n}" for k, n in self.counts().items())
        return f"Events({len(self)} events{'; ' + counts if counts else ''})"

    def same_as(self, other: "Events") -> bool:
        """Whether both tables hold the same events (the same dicts, in the same order)."""
        if len(self) != len(other) or not np.array_equal(self.steps, other.steps):
            return False
        if not np.array_equal(self.kind_names(), other.kind_names()):
            return False
        names = {n for n, c in self.columns.items() if c.mask(len(self)).any()} | {n for n, c in other.columns.items() if c.mask(len(other)).any()}
        return all(name in self.columns and name in other.columns and same_column(self.columns[name], other.columns[name], len(self))
                   for name in names)

    def kind_names(self) -> np.ndarray:
        """``(n,)`` the kind of each event, as strings."""
        return np.asarray(self.kinds, dtype=object)[self.codes] if self.kinds else np.zeros(0, object)

    def kind_mask(self, *kinds: str) -> np.ndarray:
        """``(n,)`` whether each event is of one of ``kinds``."""
        wanted = [i for i, k in enumerate(self.kinds) if k in kinds]
        return np.isin(self.codes, wanted)

    def count_of(self, kind: str) -> int:
        """How many events are of ``kind``."""
        return int(self.kind_mask(kind).sum())

    def counts(self) -> dict[str, int]:
        """Events per kind, in the order of the kind table."""
        found = np.bincount(self.codes, minlength=len(self.kinds))
        return {k: int(n) for k, n in zip(self.kinds, found)}

    def column(self, name: str, fill: Any = -1) -> np.ndarray:
        """``(n,)`` the values of a scalar field (``fill`` where an event has none; texts
        for ``string`` fields)."""
        n = len(self)
        column = self.columns.get(name)
        if column is None:
            return np.full(n, fill)
        if column.offsets is not None or column.kind == "json":
            raise ConfigError(f"events: field {name!r}: expected a field of one value per event, received a {column.kind} field")
        values = np.asarray(column.labels, dtype=object)[column.values] if column.kind == "string" else column.values
        if column.present is None:
            return values
        out = np.full(n, fill, dtype=np.result_type(values.dtype, np.asarray(fill).dtype) if values.dtype != object else object)
        out[column.present] = values[column.present]
        return out

    def take(self, index: np.ndarray) -> "Events":
        """The events at ``index`` (integers or a boolean mask), as a table."""
        index = np.flatnonzero(index) if np.asarray(index).dtype == bool else np.asarray(index, np.int64)
        return Events(self.steps[index], self.codes[index], self.kinds, {n: c.take(index) for n, c in self.columns.items()})

    # -- schema and files ----------------------------------------------------------------
    def fields_by_kind(self) -> dict[str, dict[str, str]]:
        """Event kind → its fields' column kinds (``optional …`` when some events of the kind lack it)."""
        total = np.bincount(self.codes, minlength=len(self.kinds))
        out: dict[str, dict[str, str]] = {k: {"step": "integer", "kind": "string"} for k, n in zip(self.kinds, total) if n}
        for name, column in self.columns.items():
            having = np.bincount(self.codes[column.mask(len(self))], minlength=len(self.kinds))
            for k, kind in enumerate(self.kinds):
                if having[k]:
                    out[kind][name] = ("" if having[k] == total[k] else "optional ") + column.kind
        return out

    def describe(self) -> dict[str, Any]:
        """What ``trace.json`` records of the table: ``count``, ``kinds``, and per field its
        column kind, whether some events lack it (``partial``) and its text table."""
        fields = {}
        for name, c in self.columns.items():
            entry: dict[str, Any] = {"kind": c.kind, "partial": c.present is not None}
            if c.kind in TEXT_KINDS:
                entry["labels"] = list(c.labels)
            fields[name] = entry
        return {"count": len(self), "kinds": list(self.kinds), "fields": fields}

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The columns as the arrays saved in ``trace.npz`` (see the module docstring)."""
        out = {f"{PREFIX}step": self.steps, f"{PREFIX}kind": self.codes}
        for name, c in self.columns.items():
            out[PREFIX + name] = c.values
            if c.present is not None:
                out[PREFIX + name + PRESENT] = c.present
            if c.offsets is not None:
                out[PREFIX + name + OFFSETS] = np.asarray(c.offsets, np.int64)
        return out


def same_column(a: Column, b: Column, n: int) -> bool:
    """Whether two columns give every event the same value (or both none)."""
    present = a.mask(n)
    if not np.array_equal(present, b.mask(n)):
        return False
    if a.kind != b.kind:
        kind = merge_kinds([a.kind, b.kind])
        a, b = a.as_kind(kind, n), b.as_kind(kind, n)
    if a.offsets is not None:
        counts_a, counts_b = np.diff(a.offsets)[present], np.diff(b.offsets)[present]
        return np.array_equal(counts_a, counts_b) and np.array_equal(a.take(np.flatnonzero(present)).values, b.take(np.flatnonzero(present)).values)
    if a.kind in TEXT_KINDS:
        la, lb = np.asarray(a.labels, dtype=object), np.asarray(b.labels, dtype=object)
        return bool(np.all(la[a.values[present]] == lb[b.values[present]])) if present.any() else True
    return np.array_equal(a.values[present], b.values[present])


def concat_columns(columns: list[Column | None], sizes: list[int]) -> Column:
    """One column of the events of several tables (``None``: that table lacks the field)."""
    kind = merge_kinds(c.kind for c in columns if c is not None)
    filled = []
    for c, n in zip(columns, sizes):
        if c is None:
            c = Column(kind, np.zeros(0 if kind in LIST_KINDS else n, (SCALAR_KINDS.get(kind) or LIST_KINDS.get(kind) or np.int32)),
                       np.zeros(n, bool), np.zeros(n + 1, np.int64) if kind in LIST_KINDS else None, ("null",) if kind in TEXT_KINDS else ())
        filled.append(c.as_kind(kind, n))
    present = None if all(c.present is None for c in filled) else np.concatenate([c.mask(n) for c, n in zip(filled, sizes)])
    if kind in LIST_KINDS:
        counts = np.concatenate([np.diff(c.offsets) for c in filled])
        return Column(kind, np.concatenate([c.values for c in filled]), present, np.concatenate([[0], np.cumsum(counts)]).astype(np.int64))
    if kind in TEXT_KINDS:
        labels: dict[str, int] = {}
        codes = [np.array([labels.setdefault(t, len(labels)) for t in c.labels], np.int32)[c.values] if len(c.values) else c.values
                 for c in filled]
        return Column(kind, np.concatenate(codes).astype(np.int32), present, None, tuple(labels))
    return Column(kind, np.concatenate([c.values for c in filled]), present)


class EventLog:
    """The events of a run being recorded, in order: dicts appended one at a time
    (:meth:`append`) and batches of one kind (:meth:`add`), turned into one
    :class:`Events` table at the end (:meth:`table`). Iterating it gives the dicts."""

    def __init__(self) -> None:
        self._parts: list[Events | list[dict[str, Any]]] = []
        self._size = 0

    def append(self, event: Mapping[str, Any]) -> None:
        """Append one event dict (with ``step`` and ``kind``)."""
        if not self._parts or not isinstance(self._parts[-1], list):
            self._parts.append([])
        self._parts[-1].append(dict(event))  # type: ignore[union-attr]
        self._size += 1

    def add(self, step: Any, kind: str, **fields: Any) -> None:
        """Append a batch of ``kind`` events (see :meth:`Events.batch`); nothing when it is empty."""
        batch = Events.batch(step, kind, **fields)
        if len(batch):
            self._parts.append(batch)
            self._size += len(batch)

    def __len__(self) -> int:
        return self._size

    def __iter__(self) -> Iterator[dict[str, Any]]:
        for part in self._parts:
            yield from part

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (EventLog, Events, list, tuple)):
            return self.table() == (other.table() if isinstance(other, EventLog) else other)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def count_of(self, kind: str) -> int:
        """How many events of ``kind`` were recorded."""
        return sum(p.count_of(kind) if isinstance(p, Events) else sum(e.get("kind") == kind for e in p) for p in self._parts)

    def table(self) -> Events:
        """Every event so far as one :class:`Events` table."""
        return Events.concat([p if isinstance(p, Events) else Events.from_records(p) for p in self._parts])
