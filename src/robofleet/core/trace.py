"""``Trace``: what a run recorded, saved as ``trace.npz`` + ``trace.json``.

Arrays are per-step, shaped ``(n_steps, n_robots, dim)`` (positions include the initial
state, so ``n_steps = steps + 1``); a run with ``record_every`` k > 1
(:attr:`Trace.record_every`) keeps the rows of steps 0, k, 2k, … only, its row ``j``
being step ``j·k`` (``metadata["n_steps"]`` still counts every step). Events
(``{"step": 12, "kind": "deadlock", "robot": 3}``, one per step they happened at, whatever
``record_every``) are an :class:`~robofleet.core.events.Events` table: columns saved as
arrays of ``trace.npz`` (``events.step``, ``events.kind``, ``events.robot`` …), read as a
list of dicts or by column. ``metadata`` holds what is needed to interpret the arrays
(family, dt, radius, goals, workspace...), ``results`` the scalar outcomes the simulation
decided (e.g. ``deadlock: true``), written by the family's ``metrics.py`` so that
every sweep can report them; :meth:`Trace.summary` puts the core keys in front of them.

Versions: 4 stores the events as columns (``trace.json`` describes them: count, kind table,
fields); 3 wrote them as a list of objects in ``trace.json`` with the schema, 2 without
the schema. :meth:`Trace.load` reads all three; :meth:`Trace.save` writes version 4.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ConfigError, RobofleetError, TraceError, one_line, short_repr
from .events import PREFIX as EVENT_PREFIX
from .events import Events
from .files import staged_files
from .trace_check import check_arrays, check_document, check_event_columns, schema_of
from .workspace import Region, Workspace

TRACE_VERSION = 4
READABLE_VERSIONS = (2, 3, 4)
"""Versions :meth:`Trace.load` reads: 4 stores events as columns of ``trace.npz``, 3 as a
list in ``trace.json`` with the schema of what it wrote, 2 without the schema."""
TRACE_KEYS = ("family", "events", "metadata", "results")
"""The keys of ``trace.json`` besides ``version``, ``workspace`` and ``schema``."""
TRACE_FILES = ("trace.npz", "trace.json")
CORE_SUMMARY_KEYS = ("family", "scenario", "seed", "success", "n_robots", "n_steps", "wall_seconds")
"""The keys every family's summary starts with."""


@dataclass
class Trace:
    """A recorded run.

    Attributes
    ----------
    family: the scenario family (``"avoidance"``, ``"coordination"``, ...).
    arrays: name → array; ``positions`` (true positions) is expected for motion families.
    events: the events (:class:`~robofleet.core.events.Events`, each with at least ``step``
        and ``kind``): reads as a list of dicts, or by column for large runs; a list of
        dicts given here is turned into the table.
    metadata: JSON-serialisable description of the run (``dt``, ``radius``, ``seed``...).
    results: scalar outcomes decided by the simulation, merged into :meth:`summary`.
    workspace: the workspace the run took place in, if any.
    """

    family: str
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    events: Events = field(default_factory=Events.empty)
    metadata: dict[str, Any] = field(default_factory=dict)
    results: dict[str, Any] = field(default_factory=dict)
    workspace: Workspace | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.events, Events):
            self.events = Events.from_records(self.events)

    @property
    def positions(self) -> np.ndarray:
        """True positions ``(n_steps + 1, n_robots, dim)`` (the kept states with ``record_every``)."""
        return self.arrays["positions"]

    @property
    def seed(self) -> int:
        """The seed the run used: ``simulate(spec, seed=trace.seed)`` replays it exactly."""
        return int(self.metadata["seed"])

    @property
    def record_every(self) -> int:
        """Steps between two kept rows (1: every step; state row ``j`` is the state after ``j · record_every`` steps)."""
        return int(self.metadata.get("record_every", 1))

    @property
    def scenario(self) -> str:
        """The scenario's name (its file stem when it has no ``name``)."""
        return str(self.metadata.get("scenario", ""))

    def summary(self) -> dict[str, Any]:
        """The dict written to ``summary.json`` and to every sweep row.

        The core keys (:data:`CORE_SUMMARY_KEYS`: ``family``, ``scenario``, ``seed``,
        ``success``, ``n_robots``, ``n_steps``, ``wall_seconds``) first, then the
        family's own per-run results (``results``, written by its ``metrics.py``).
        """
        md = self.metadata
        core = {"family": self.family, "scenario": md.get("scenario", ""), "seed": md.get("seed"),
                "success": bool(self.results.get("success", False)), "n_robots": md.get("n_robots"),
                "n_steps": md.get("n_steps"), "wall_seconds": md.get("wall_seconds")}
        return to_plain({**core, **{k: v for k, v in self.results.items() if k not in core}})

    def save(self, directory: str | Path) -> Path:
        """Write ``trace.npz`` (the arrays and the event columns) and ``trace.json``
        (metadata, results, workspace, the events' description and the schema) into
        ``directory`` (created if needed).

        Both files replace an earlier trace's together (:func:`~robofleet.core.files.staged_files`):
        stopped at any moment, the directory holds the earlier trace or this one, complete.
        The arrays are written one after the other, each in chunks of
        :data:`SAVE_CHUNK_BYTES` (:func:`write_npz`), so saving needs little memory beyond
        the arrays themselves.

        Raises
        ------
        ConfigError
            An array's name starts with ``events.`` (the names of the event columns).
        """
        d = Path(directory)
        arrays = {name: np.asarray(array) for name, array in self.arrays.items()}
        clash = next((name for name in arrays if name.startswith(EVENT_PREFIX)), None)
        if clash is not None:
            raise ConfigError(f"arrays: {clash}: expected a name not starting with {EVENT_PREFIX!r} (the event columns), received {clash!r}")
        stored = {**arrays, **self.events.to_arrays()}
        doc = to_plain({"version": TRACE_VERSION, "family": self.family, "events": self.events.describe(), "metadata": self.metadata,
                        "results": self.results, "workspace": _workspace_to_json(self.workspace)}, json_safe=True)
        doc["schema"] = schema_of(doc, stored, self.events)
        with staged_files(d, TRACE_FILES) as staging:
            write_npz(staging.path / "trace.npz", stored)
            (staging.path / "trace.json").write_text(dumps_json(doc), encoding="utf-8")
        return d

    @classmethod
    def load(cls, directory: str | Path) -> "Trace":
        """Read a trace written by :meth:`save`, checking everything it reads
        (:mod:`~robofleet.core.trace_check`).

        Raises
        ------
        TraceError
            ``directory`` is not a path, or holds no readable, complete trace of a known
            version, or one whose content breaks a rule of :mod:`~robofleet.core.trace_check`
            (the message names the file and the field).
        """
        if not isinstance(directory, (str, Path)):
            raise TraceError(f"directory: expected a trace directory path, received {short_repr(directory)}")
        d = Path(directory)
        doc = _read_document(d / "trace.json")
        arrays = _read_arrays(d / "trace.npz")
        check_arrays(arrays, doc, str(d / "trace.npz"))
        columns = {name: arrays.pop(name) for name in [n for n in arrays if n.startswith(EVENT_PREFIX)]} if doc["version"] >= 4 else {}
        events = check_event_columns(doc, columns, str(d / "trace.json"), str(d / "trace.npz")) if doc["version"] >= 4 \
            else Events.from_records(doc["events"])
        try:
            workspace = _workspace_from_json(doc.get("workspace"))
        except (KeyError, TypeError, ValueError, AttributeError, RobofleetError) as exc:
            raise TraceError(f"{d / 'trace.json'}: workspace: expected bounds, obstacles and regions, received an unreadable one ({one_line(exc)})") from None
        return cls(doc["family"], arrays, events, doc["metadata"], doc["results"], workspace)


SAVE_CHUNK_BYTES = 1 << 20
"""Bytes of an array copied and deflated at a time by :func:`write_npz`."""


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` as a compressed ``.npz`` (what ``np.load`` reads, as
    ``np.savez_compressed`` writes it), each array row block by row block, at most
    :data:`SAVE_CHUNK_BYTES` (or one row) copied at a time."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as archive:
        for name, array in arrays.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                header = {"descr": np.lib.format.dtype_to_descr(array.dtype), "fortran_order": False, "shape": array.shape}
                np.lib.format.write_array_header_1_0(member, header)
                if array.ndim == 0:
                    member.write(array.tobytes())
                    continue
                rows = max(1, SAVE_CHUNK_BYTES // max(1, array[:1].nbytes))
                for start in range(0, len(array), rows):
                    member.write(np.ascontiguousarray(array[start:start + rows]).tobytes())


def _read_document(path: Path) -> dict[str, Any]:
    """``trace.json``, parsed and checked (:func:`~robofleet.core.trace_check.check_document`)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise TraceError(f"{path}: expected a trace directory holding trace.json and trace.npz, received no readable "
                         f"{path.name} ({getattr(exc, 'strerror', None) or one_line(exc)})") from None
    except ValueError as exc:
        raise TraceError(f"{path}: expected JSON, received text that is not ({one_line(exc)})") from None
    if not isinstance(doc, dict) or doc.get("version") not in READABLE_VERSIONS:
        received = doc.get("version") if isinstance(doc, dict) else type(doc).__name__
        raise TraceError(f"{path}: version: expected one of {list(READABLE_VERSIONS)}, received {short_repr(received)}")
    missing = [key for key in TRACE_KEYS + (("schema",) if doc["version"] >= 3 else ()) if key not in doc]
    if missing:
        raise TraceError(f"{path}: expected the keys {list(TRACE_KEYS)}, received none for {missing}")
    check_document(doc, str(path))
    return doc


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every array of ``trace.npz`` (read in full, so a damaged member shows here)."""
    try:
        with np.load(path, allow_pickle=False) as npz:
            return {k: npz[k] for k in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, KeyError) as exc:
        raise TraceError(f"{path}: expected a trace directory holding trace.json and trace.npz, received no readable "
                         f"{path.name} ({getattr(exc, 'strerror', None) or one_line(exc)})") from None


def _workspace_to_json(ws: Workspace | None):
    if ws is None:
        return None
    return {
        "bounds": ws.bounds.tolist(),
        "obstacles": [o.tolist() for o in ws.obstacles],
        "regions": [{"name": r.name, "vertices": r.vertices.tolist(), "attributes": dict(r.attributes)} for r in ws.regions],
    }


def _workspace_from_json(doc) -> Workspace | None:
    if doc is None:
        return None
    regions = tuple(Region(r["name"], np.asarray(r["vertices"], float), r["attributes"]) for r in doc["regions"])
    return Workspace(np.asarray(doc["bounds"], float), tuple(np.asarray(o, float) for o in doc["obstacles"]), regions)


def to_plain(obj: Any, *, json_safe: bool = False) -> Any:
    """Convert numpy scalars/arrays (recursively) to plain Python.

    With ``json_safe`` non-finite floats become ``None`` so the output is strict JSON.
    """
    if isinstance(obj, dict):
        return {str(k): to_plain(v, json_safe=json_safe) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v, json_safe=json_safe) for v in obj]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "biu" or (obj.dtype.kind == "f" and (not json_safe or np.isfinite(obj).all())):
            return obj.tolist()  # numbers only: tolist already gives plain Python scalars
        return to_plain(obj.tolist(), json_safe=json_safe)
    if isinstance(obj, np.generic):
        obj = obj.item()
    if json_safe and isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def dumps_json(obj: Any) -> str:
    """Strict JSON text of ``obj`` (numpy converted, NaN/inf as ``null``)."""
    return json.dumps(to_plain(obj, json_safe=True), indent=1, allow_nan=False)
