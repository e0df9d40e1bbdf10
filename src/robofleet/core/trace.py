"""``Trace``: what a run recorded, saved as ``trace.npz`` + ``trace.json``.

Arrays are per-step, shaped ``(n_steps, n_robots, dim)`` (positions include the initial
state, so ``n_steps = steps + 1``); a run with ``record_every`` k > 1
(:attr:`Trace.record_every`) keeps the rows of steps 0, k, 2k, … only, its row ``j``
being step ``j·k`` (``metadata["n_steps"]`` still counts every step). Events are small dicts (``{"step": 12, "kind":
"deadlock", "robot": 3}``). ``metadata`` holds what is needed to interpret the arrays
(family, dt, radius, goals, workspace...), ``results`` the scalar outcomes the simulation
decided (e.g. ``deadlock: true``), written by the family's ``metrics.py`` so that
every sweep can report them; :meth:`Trace.summary` puts the core keys in front of them.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import RobofleetError, TraceError, short_repr
from .workspace import Region, Workspace

TRACE_VERSION = 2
TRACE_KEYS = ("family", "events", "metadata", "results")
"""The keys of ``trace.json`` besides ``version`` and ``workspace``."""
CORE_SUMMARY_KEYS = ("family", "scenario", "seed", "success", "n_robots", "n_steps", "wall_seconds")
"""The keys every family's summary starts with."""


@dataclass
class Trace:
    """A recorded run.

    Attributes
    ----------
    family: the scenario family (``"avoidance"``, ``"coordination"``, ...).
    arrays: name → array; ``positions`` (true positions) is expected for motion families.
    events: list of event dicts, each with at least ``step`` and ``kind``.
    metadata: JSON-serialisable description of the run (``dt``, ``radius``, ``seed``...).
    results: scalar outcomes decided by the simulation, merged into :meth:`summary`.
    workspace: the workspace the run took place in, if any.
    """

    family: str
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    events: list[dict] = field(default_factory=list)
    metadata: dict[str, Any] = field(default_factory=dict)
    results: dict[str, Any] = field(default_factory=dict)
    workspace: Workspace | None = None

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
        """Write ``trace.npz`` and ``trace.json`` into ``directory`` (created if needed)."""
        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(d / "trace.npz", **self.arrays)
        doc = {
            "version": TRACE_VERSION,
            "family": self.family,
            "events": self.events,
            "metadata": self.metadata,
            "results": self.results,
            "workspace": _workspace_to_json(self.workspace),
        }
        (d / "trace.json").write_text(dumps_json(doc))
        return d

    @classmethod
    def load(cls, directory: str | Path) -> "Trace":
        """Read a trace written by :meth:`save`.

        Raises
        ------
        TraceError
            ``directory`` is not a path, or holds no readable, complete trace of this version.
        """
        if not isinstance(directory, (str, Path)):
            raise TraceError(f"directory: expected a trace directory path, received {short_repr(directory)}")
        d = Path(directory)
        try:
            doc = json.loads((d / "trace.json").read_text())
            with np.load(d / "trace.npz", allow_pickle=False) as npz:
                arrays = {k: npz[k] for k in npz.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise TraceError(f"{d}: expected a trace directory with trace.json and trace.npz, received an unreadable one ({exc})") from None
        if not isinstance(doc, dict) or doc.get("version") != TRACE_VERSION:
            received = doc.get("version") if isinstance(doc, dict) else type(doc).__name__
            raise TraceError(f"{d / 'trace.json'}: version: expected {TRACE_VERSION}, received {received!r}")
        missing = [key for key in TRACE_KEYS if key not in doc]
        if missing:
            raise TraceError(f"{d / 'trace.json'}: expected the keys {list(TRACE_KEYS)}, received none for {missing}")
        try:
            workspace = _workspace_from_json(doc.get("workspace"))
        except (KeyError, TypeError, ValueError, RobofleetError) as exc:
            raise TraceError(f"{d / 'trace.json'}: workspace: expected bounds, obstacles and regions, received an unreadable one ({exc})") from None
        return cls(doc["family"], arrays, doc["events"], doc["metadata"], doc["results"], workspace)


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
