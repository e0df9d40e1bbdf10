"""What a trace file may hold: the checks :meth:`~robofleet.core.trace.Trace.load` makes
before it returns a trace, so that a damaged but parseable trace is refused with one line
naming the file and the field rather than failing later, somewhere else.

Rules, for every trace:

* ``family`` is a non-empty string; ``metadata`` and ``results`` are objects;
* events (version 4, :mod:`~robofleet.core.events`): ``trace.json``'s ``events`` is an
  object with ``count`` (an integer ≥ 0), ``kinds`` (distinct non-empty strings) and
  ``fields`` (each a column kind, whether some events lack it, and its text table for
  ``string`` and ``json`` fields); ``trace.npz`` holds ``events.step`` (``count`` integers
  in ``[0, n_steps]``), ``events.kind`` (``count`` codes into ``kinds``) and each field's
  column: values of its kind (codes into its table for texts), a ``:present`` mask of
  ``count`` booleans when partial, ``:offsets`` (``count + 1`` integers from 0, never
  decreasing, ending at the number of items) for lists; a ``robot`` field holds robot
  indices in ``[0, n_robots)``; no other ``events.`` array;
* events (versions 2 and 3): ``events`` is a list of objects, each with an integer
  ``step`` in ``[0, n_steps]``, a non-empty string ``kind`` and, if it names one, an
  integer ``robot`` in ``[0, n_robots)``;
* the core metadata (:data:`CORE_METADATA`) have their types: ``scenario`` a string,
  ``seed`` an integer ≥ 0 (or null), ``n_robots``, ``n_steps`` integers ≥ 0,
  ``max_steps``, ``record_every`` integers ≥ 1, ``wall_seconds`` a number (or null);
* every array holds numbers or booleans; ``positions`` is ``(rows, n_robots, dim)`` with
  ``rows = n_steps // record_every + 1``; ``step_seconds`` has ``n_steps`` numbers;
  ``arrival_steps`` has ``n_robots`` integers.

A trace written by this version also records, in ``trace.json``, the *schema* of what it
wrote (:func:`schema_of`): the kind of every metadata and results value, the fields of
each event kind, and the dtype and shape of every array (the event columns included). Loading checks the file against
it, so a value whose kind changed since it was written (a number turned into a string, a
list into a number, a field or an array removed, an array reshaped or retyped) is named.
A kind is ``null``, ``boolean``, ``integer``, ``number``, ``string``, ``object``, or
``list of K`` for a list whose items are all of kind ``K`` (``list`` when empty, ``list of
mixed`` otherwise); an integer is accepted where a number was written.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .budget import recorded_rows
from .errors import TraceError, short_repr
from .events import COLUMN_KINDS, LIST_KINDS, OFFSETS, PREFIX, PRESENT, SCALAR_KINDS, TEXT_KINDS, Column, Events

CORE_METADATA = {  # field: (kind, minimum, null allowed)
    "scenario": ("string", None, False),
    "seed": ("integer", 0, True),
    "n_robots": ("integer", 0, False),
    "n_steps": ("integer", 0, False),
    "max_steps": ("integer", 1, False),
    "record_every": ("integer", 1, False),
    "wall_seconds": ("number", None, True),
}
ARRAY_KINDS = "biuf"
"""numpy dtype kinds an array may have: booleans, integers, floats."""
MIXED = "mixed"
OPTIONAL = "optional "


# -- kinds -------------------------------------------------------------------------------
def kind_of(value: Any) -> str:
    """The kind of a JSON value (see the module docstring)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, dict):
        return "object"
    if isinstance(value, list):
        if not value:
            return "list"
        return f"list of {common_kind(kind_of(item) for item in value)}"
    return type(value).__name__


def common_kind(kinds) -> str:
    """The one kind of items of these kinds: it, ``number`` for integers and numbers, else ``mixed``."""
    found = set(kinds)
    if found == {"integer", "number"}:
        return "number"
    return found.pop() if len(found) == 1 else MIXED


def accepts(expected: str, received: str) -> bool:
    """Whether a value of kind ``received`` may stand where one of kind ``expected`` was written."""
    for want, got in zip(expected.split(" of "), received.split(" of ")):
        if want == MIXED or want == got:
            continue
        if want == "number" and got == "integer":
            continue
        return False
    return True


def schema_of(doc: Mapping[str, Any], arrays: Mapping[str, np.ndarray], events: Events) -> dict[str, Any]:
    """The schema of a plain trace document (its ``metadata`` and ``results``), of its
    events (the fields of each kind, from the columns) and of its arrays, as written into
    ``trace.json``."""
    return {
        "metadata": {k: kind_of(v) for k, v in doc["metadata"].items()},
        "results": {k: kind_of(v) for k, v in doc["results"].items()},
        "events": events.fields_by_kind(),
        "arrays": {name: {"dtype": str(a.dtype), "shape": list(a.shape)} for name, a in arrays.items()},
    }


# -- the checks --------------------------------------------------------------------------
def check_document(doc: dict[str, Any], where: str) -> None:
    """Check ``trace.json``'s content (named ``where`` in messages) but the workspace."""
    family, metadata, results, events = doc["family"], doc["metadata"], doc["results"], doc["events"]
    if not isinstance(family, str) or not family:
        fail(where, "family", "a family name", family)
    for key, value in (("metadata", metadata), ("results", results)):
        if not isinstance(value, dict):
            fail(where, key, "an object", value)
    columnar = doc.get("version", 0) >= 4
    if columnar:
        check_event_table(events, where)
    elif not isinstance(events, list):
        fail(where, "events", "a list of events", events)
    for name, (kind, minimum, nullable) in CORE_METADATA.items():
        if name in metadata:
            check_core_value(metadata[name], f"metadata.{name}", kind, minimum, nullable, where)
    schema = doc.get("schema")
    if schema is not None or doc.get("version", 0) >= 3:  # version 3 records its schema
        check_schema_shape(schema, where)
        check_values(metadata, schema["metadata"], "metadata", where)
        check_values(results, schema["results"], "results", where)
    for index, event in enumerate([] if columnar else events):
        check_event(event, index, metadata, (schema or {}).get("events"), where)


def check_core_value(value: Any, field: str, kind: str, minimum: int | None, nullable: bool, where: str) -> None:
    if value is None and nullable:
        return
    if not accepts(kind, kind_of(value)) or (minimum is not None and value < minimum):
        bound = f" ≥ {minimum}" if minimum is not None else ""
        fail(where, field, f"{'an' if kind == 'integer' else 'a'} {kind}{bound}{' or null' if nullable else ''}", value)


def check_schema_shape(schema: Any, where: str) -> None:
    """The schema itself: kinds (strings) for metadata, results and each event kind's
    fields, a dtype and a shape for each array."""
    if not isinstance(schema, dict) or any(not isinstance(schema.get(k), dict) for k in ("metadata", "results", "events", "arrays")):
        fail(where, "schema", "an object with metadata, results, events and arrays", schema)
    for part in ("metadata", "results"):
        for name, kind in schema[part].items():
            if not isinstance(kind, str):
                fail(where, f"schema.{part}.{name}", "a kind", kind)
    for event_kind, fields in schema["events"].items():
        if not isinstance(fields, dict) or any(not isinstance(kind, str) for kind in fields.values()):
            fail(where, f"schema.events.{event_kind}", "an object of kinds", fields)
    for name, entry in schema["arrays"].items():
        if not (isinstance(entry, dict) and isinstance(entry.get("dtype"), str) and isinstance(entry.get("shape"), list)
                and all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in entry["shape"])):
            fail(where, f"schema.arrays.{name}", "a dtype and a shape", entry)


def check_values(values: dict[str, Any], kinds: dict[str, Any], part: str, where: str) -> None:
    """Each field the schema lists is present with a kind it accepts."""
    for name, kind in kinds.items():
        if name not in values:
            fail(where, f"{part}.{name}", f"a value of kind {kind} (as written)", None, received="nothing")
        if not accepts(kind, kind_of(values[name])):
            fail(where, f"{part}.{name}", f"a value of kind {kind} (as written)", values[name])


def check_event(event: Any, index: int, metadata: dict[str, Any], kinds: dict[str, Any] | None, where: str) -> None:
    field = f"events[{index}]"
    if not isinstance(event, dict):
        fail(where, field, "an object with step and kind", event)
    n_steps, n_robots = metadata.get("n_steps"), metadata.get("n_robots")
    step = event.get("step")
    if kind_of(step) != "integer" or step < 0 or (isinstance(n_steps, int) and step > n_steps):
        bounds = f" in [0, {n_steps}] (n_steps)" if isinstance(n_steps, int) else " ≥ 0"
        fail(where, f"{field}.step", f"an integer{bounds}", step, received=None if "step" in event else "nothing")
    if not isinstance(event.get("kind"), str) or not event["kind"]:
        fail(where, f"{field}.kind", "a non-empty string", event.get("kind"), received=None if "kind" in event else "nothing")
    if "robot" in event:
        robot = event["robot"]
        if kind_of(robot) != "integer" or robot < 0 or (isinstance(n_robots, int) and robot >= n_robots):
            fail(where, f"{field}.robot", f"a robot index in [0, {n_robots})", robot)
    for name, kind in (kinds or {}).get(event["kind"], {}).items():
        required = not kind.startswith(OPTIONAL)
        kind = kind.removeprefix(OPTIONAL)
        if name not in event:
            if required:
                fail(where, f"{field}.{name}", f"a value of kind {kind} (as in every {event['kind']} event written)", None, received="nothing")
        elif not accepts(kind, kind_of(event[name])):
            fail(where, f"{field}.{name}", f"a value of kind {kind} (as written)", event[name])


def check_event_table(table: Any, where: str) -> None:
    """``trace.json``'s description of the event columns (version 4)."""
    if not isinstance(table, dict) or any(key not in table for key in ("count", "kinds", "fields")):
        fail(where, "events", "an object with count, kinds and fields", table)
    if kind_of(table["count"]) != "integer" or table["count"] < 0:
        fail(where, "events.count", "an integer ≥ 0", table["count"])
    kinds = table["kinds"]
    if not isinstance(kinds, list) or any(not isinstance(k, str) or not k for k in kinds) or len(set(kinds)) != len(kinds):
        fail(where, "events.kinds", "a list of distinct non-empty strings", kinds)
    if not isinstance(table["fields"], dict):
        fail(where, "events.fields", "an object", table["fields"])
    for name, entry in table["fields"].items():
        field = f"events.fields.{name}"
        if name in ("step", "kind") or not isinstance(entry, dict) or entry.get("kind") not in COLUMN_KINDS \
                or not isinstance(entry.get("partial"), bool):
            fail(where, field, f"an object with a kind (one of {list(COLUMN_KINDS)}) and partial (true or false)", entry)
        labels = entry.get("labels")
        if entry["kind"] in TEXT_KINDS and (not isinstance(labels, list) or any(not isinstance(t, str) for t in labels)):
            fail(where, f"{field}.labels", "a list of strings", labels, received=None if "labels" in entry else "nothing")


def check_event_columns(doc: dict[str, Any], columns: dict[str, np.ndarray], json_where: str, where: str) -> Events:
    """The event columns of ``trace.npz`` (named ``where``) against their description in
    ``trace.json`` (named ``json_where``) and the metadata; the table they make."""
    table, metadata = doc["events"], doc["metadata"]
    count, kinds = table["count"], table["kinds"]
    n_steps, n_robots = metadata.get("n_steps"), metadata.get("n_robots")
    expected = {PREFIX + "step", PREFIX + "kind"}
    steps = event_array(columns, "step", None, "iu", where)
    if len(steps) != count:
        fail(json_where, "events.count", f"the number of events in {where} ({len(steps)})", count)
    bound_values(steps, 0, n_steps if isinstance(n_steps, int) else None, PREFIX + "step", "steps", "n_steps", where)
    codes = event_array(columns, "kind", count, "iu", where)
    bound_values(codes, 0, len(kinds) - 1, PREFIX + "kind", "codes into events.kinds", f"{len(kinds)} kinds in {json_where}", where)
    fields = {}
    for name, entry in table["fields"].items():
        kind = entry["kind"]
        present = offsets = None
        if entry["partial"]:
            present = event_array(columns, name + PRESENT, count, "b", where)
            expected.add(PREFIX + name + PRESENT)
        if kind in LIST_KINDS:
            offsets = event_array(columns, name + OFFSETS, count + 1, "iu", where)
            expected.add(PREFIX + name + OFFSETS)
        dtype_kinds = {"integer": "iu", "number": "fiu", "boolean": "b"}.get(kind.removeprefix("list of "), "iu")
        values = event_array(columns, name, None if offsets is not None else count, dtype_kinds, where)
        expected.add(PREFIX + name)
        if offsets is not None and (len(offsets) and offsets[0] != 0 or np.any(np.diff(offsets) < 0) or offsets[-1] != len(values)):
            fail(where, PREFIX + name + OFFSETS, f"offsets from 0, never decreasing, ending at {len(values)} (the items)", None,
                 received="others")
        shown = values if present is None or offsets is not None else values[present]
        if kind in TEXT_KINDS:
            labels = entry["labels"]
            bound_values(shown, 0, len(labels) - 1, PREFIX + name, "codes into its table", f"{len(labels)} texts in {json_where}", where)
        if name == "robot" and kind == "integer":
            bound_values(shown, 0, n_robots - 1 if isinstance(n_robots, int) else None, PREFIX + name, "robot indices", "n_robots", where)
        dtype = SCALAR_KINDS.get(kind.removeprefix("list of "), np.int32)
        fields[name] = Column(kind, values.astype(dtype, copy=False), present, offsets, tuple(entry.get("labels") or ()))
    extra = sorted(set(columns) - expected)
    if extra:
        fail(where, extra[0], f"only the event columns {json_where} describes", None, received=f"the undescribed array {extra[0]!r}")
    return Events(steps, codes, kinds, fields)


def event_array(columns: dict[str, np.ndarray], name: str, rows: int | None, kinds: str, where: str) -> np.ndarray:
    """The event column ``events.<name>``: one-dimensional, of dtype kinds ``kinds``, ``rows`` long (when given)."""
    array = columns.get(PREFIX + name)
    words = {"iu": "integers", "fiu": "numbers", "b": "booleans"}[kinds]
    if array is None or array.ndim != 1 or array.dtype.kind not in kinds or (rows is not None and len(array) != rows):
        fail(where, PREFIX + name, f"{rows if rows is not None else 'a list of'} {words}", None,
             received="nothing" if array is None else f"{array.shape} of {array.dtype}")
    return array


def bound_values(values: np.ndarray, low: int, high: int | None, name: str, what: str, source: str, where: str) -> None:
    """Every value in ``[low, high]`` (``high`` ``None``: no upper bound)."""
    if not len(values):
        return
    lo, hi = values.min(), values.max()
    if lo < low or (high is not None and hi > high):
        bad = lo if lo < low else hi
        span = f"[{low}, {high}] ({source})" if high is not None else f"≥ {low}"
        fail(where, name, f"{what} in {span}", bad.item())


def check_arrays(arrays: dict[str, np.ndarray], doc: dict[str, Any], where: str) -> None:
    """Check ``trace.npz``'s arrays (named ``where``) against the metadata and the schema."""
    for name, array in arrays.items():
        if array.dtype.kind not in ARRAY_KINDS:
            fail(where, name, "an array of numbers or booleans", array.dtype, received=f"dtype {array.dtype}")
    schema = (doc.get("schema") or {}).get("arrays")
    if schema is not None:
        for name, entry in schema.items():
            if name not in arrays:
                fail(where, name, f"an array {tuple(entry['shape'])} of {entry['dtype']} (as trace.json lists)", None, received="nothing")
            array = arrays[name]
            if str(array.dtype) != entry["dtype"] or list(array.shape) != entry["shape"]:
                fail(where, name, f"an array {tuple(entry['shape'])} of {entry['dtype']} (as trace.json lists)", None,
                     received=f"{array.shape} of {array.dtype}")
        extra = sorted(set(arrays) - set(schema))
        if extra:
            fail(where, extra[0], "only the arrays trace.json lists", None, received=f"the unlisted array {extra[0]!r}")
    check_core_arrays(arrays, doc["metadata"], where)


def check_core_arrays(arrays: dict[str, np.ndarray], metadata: dict[str, Any], where: str) -> None:
    """``positions``, ``step_seconds`` and ``arrival_steps`` agree with ``n_steps``, ``n_robots``, ``record_every``."""
    n_steps, n_robots = metadata.get("n_steps"), metadata.get("n_robots")
    every = metadata.get("record_every", 1)
    if "positions" in arrays:
        positions = arrays["positions"]
        rows = recorded_rows(n_steps, every) if isinstance(n_steps, int) else None
        if positions.ndim != 3 or (rows is not None and positions.shape[0] != rows) \
                or (isinstance(n_robots, int) and positions.shape[1] != n_robots) or positions.dtype.kind == "b":
            fail(where, "positions", f"numbers shaped ({rows if rows is not None else 'rows'}, "
                 f"{n_robots if isinstance(n_robots, int) else 'n_robots'}, dim) (n_steps {n_steps}, record_every {every} in "
                 "trace.json)", None, received=f"{positions.shape} of {positions.dtype}")
    if "step_seconds" in arrays:
        seconds = arrays["step_seconds"]
        if seconds.ndim != 1 or (isinstance(n_steps, int) and len(seconds) != n_steps) or seconds.dtype.kind != "f":
            fail(where, "step_seconds", f"{n_steps} numbers (n_steps in trace.json)", None, received=f"{seconds.shape} of {seconds.dtype}")
    if "arrival_steps" in arrays:
        arrivals = arrays["arrival_steps"]
        if arrivals.ndim != 1 or (isinstance(n_robots, int) and len(arrivals) != n_robots) or arrivals.dtype.kind not in "iu":
            fail(where, "arrival_steps", f"{n_robots} integers (n_robots in trace.json)", None,
                 received=f"{arrivals.shape} of {arrivals.dtype}")


def fail(where: str, field: str, expected: str, value: Any, *, received: str | None = None) -> None:
    """Raise the one-line :class:`TraceError` ``where: field: expected …, received …``."""
    raise TraceError(f"{where}: {field}: expected {expected}, received {received if received is not None else short_repr(value)}")
