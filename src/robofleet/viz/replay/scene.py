"""A :class:`Scene`: everything a replay shows, family-independent and ready to embed.

A family's figures module turns a trace into a scene (``replay_scene(trace)``); the HTML
page (:mod:`robofleet.viz.replay.page`) and the Rerun recording
(:mod:`robofleet.viz.replay.rerun_export`) draw any scene the same way, so every family
gets every viewer. A scene holds

* the frames: the recorded state index and the simulated time of each frame;
* the robots: coordinates per frame (2-D or 3-D), a colour each, an optional status per
  frame (waiting, arrived, failed ...) and per-frame fields shown when a robot is hovered;
* views: planes of the coordinates (top, side, the leader's frame ...), each with axis
  labels in units and its extent;
* static shapes (obstacles, goals, planned paths, the grid) and per-frame layers
  (cells, ellipses, arrows, marks, vertices revealed at a frame), each in a named
  *group* the page can toggle;
* events (deadlocks, flips, failures ...) placed on frames, and the legend.

Arrays are kept as numpy arrays; :meth:`Scene.to_document` encodes them compactly
(little-endian typed arrays, zlib-deflated, base64) for the page.
"""

from __future__ import annotations

import base64
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...core.errors import ConfigError

SCENE_VERSION = 1
TAB10 = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
ROBOT_PALETTE = TAB10 + ("#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#c7c7c7",
                         "#dbdb8d", "#9edae5")
"""Robot colours (tab20 order: the ten strong ones first)."""
_DTYPES = {"f4": np.float32, "i4": np.int32, "u1": np.uint8}


@dataclass
class View:
    """One plane of the robots' coordinates.

    Attributes
    ----------
    name: shown above the canvas ("top view (x, y)").
    axes: the two coordinate indices drawn horizontally and vertically.
    labels: axis labels with units ("x [m]").
    lo, hi: lower and upper corner of the drawn area, in the view's coordinates.
    source: ``"positions"`` or the name of an array in :attr:`Scene.coordinates`.
    """

    name: str
    axes: tuple[int, int]
    labels: tuple[str, str]
    lo: Sequence[float]
    hi: Sequence[float]
    source: str = "positions"


@dataclass
class Shape:
    """A static shape: ``polygon``, ``polyline``, ``points`` or ``text``, in one view.

    ``points`` is ``(k, 2)`` in the view's coordinates; ``style`` holds ``fill``,
    ``stroke``, ``width`` (px), ``dash``, ``alpha``, ``marker`` and ``size`` (px).
    ``robot`` colours the shape like that robot when the style says ``"robot"``.
    """

    kind: str
    group: str
    points: np.ndarray
    style: dict[str, Any] = field(default_factory=dict)
    view: int = 0
    robot: int = -1
    text: str = ""


@dataclass
class Layer:
    """A per-frame layer in one view.

    Kinds and their arrays (``offsets`` is ``(n_frames + 1,)``: the items of frame ``k``
    are rows ``offsets[k]:offsets[k+1]``):

    * ``segments``: ``xy (S, 4)`` (from, to), ``robot (S,)``; arrows when ``style["arrow"]``;
    * ``marks``: ``xy (M, 2)``, ``robot (M,)``; drawn with ``style["marker"]``;
    * ``ellipses``: ``xy (E, 2)`` centres, ``shape (E, 3)`` full width, height [length
      units] and angle [rad], ``robot (E,)``;
    * ``polygons``: ``polygon (P + 1,)`` offsets into ``vertices (V, 2)``, ``robot (P,)``
      (here ``offsets`` indexes polygons);
    * ``reveal``: ``xy (P, 2)`` and ``frame (P,)``: point ``p`` is shown from frame
      ``frame[p]`` on (``-1``: never); no ``offsets``.
    """

    kind: str
    group: str
    arrays: dict[str, np.ndarray]
    style: dict[str, Any] = field(default_factory=dict)
    view: int = 0

    def is_empty(self) -> bool:
        """Whether the layer would draw nothing at any frame."""
        if self.kind == "reveal":
            return not (self.arrays["frame"] >= 0).any()
        return int(self.arrays["offsets"][-1]) == 0


@dataclass
class Field:
    """A value shown when a robot is hovered: ``values`` is ``(n_frames, n_robots)`` (per
    robot) or ``(n_frames,)`` (the team's), kept as float32 (what the page embeds);
    ``labels`` names integer codes, if any."""

    name: str
    values: np.ndarray
    unit: str = ""
    labels: Sequence[str] | None = None
    digits: int = 3

    def __post_init__(self) -> None:
        self.values = np.asarray(self.values, np.float32)  # the precision the page shows


@dataclass
class Event:
    """Something that happened at a frame (``robot = -1``: no single robot; ``step``: the
    simulation step it happened at, ``-1``: not known)."""

    frame: int
    kind: str
    robot: int = -1
    text: str = ""
    step: int = -1


@dataclass
class SceneEvents:
    """The events of a scene as columns, ordered by frame: ``frame``, ``kind`` (an index
    into ``kinds``), ``robot`` (``-1``: none), ``step`` (the simulation step) and ``text``
    (an index into ``texts``, ``-1``: none), all ``(E,)``. Iterating gives :class:`Event` s."""

    frame: np.ndarray
    kind: np.ndarray
    robot: np.ndarray
    step: np.ndarray
    text: np.ndarray
    kinds: tuple[str, ...] = ()
    texts: tuple[str, ...] = ()

    @classmethod
    def empty(cls) -> "SceneEvents":
        zero = np.zeros(0, np.int64)
        return cls(zero, zero, zero, zero, zero)

    @classmethod
    def of(cls, events: "Sequence[Event] | SceneEvents") -> "SceneEvents":
        """A list of :class:`Event` as columns (a :class:`SceneEvents` as it is)."""
        if isinstance(events, SceneEvents):
            return events
        kinds = list(dict.fromkeys(e.kind for e in events))
        texts = list(dict.fromkeys(e.text for e in events if e.text))
        column = lambda values: np.array(values, np.int64).reshape(-1)  # noqa: E731
        return cls(column([e.frame for e in events]), column([kinds.index(e.kind) for e in events]),
                   column([e.robot for e in events]), column([e.step for e in events]),
                   column([texts.index(e.text) if e.text else -1 for e in events]), tuple(kinds), tuple(texts)).by_frame()

    def by_frame(self) -> "SceneEvents":
        """The events in frame order (stable: events of one frame keep their order)."""
        order = np.argsort(self.frame, kind="stable")
        return SceneEvents(self.frame[order], self.kind[order], self.robot[order], self.step[order], self.text[order],
                           self.kinds, self.texts)

    def __len__(self) -> int:
        return len(self.frame)

    def __iter__(self):
        for f, k, r, s, t in zip(self.frame.tolist(), self.kind.tolist(), self.robot.tolist(), self.step.tolist(), self.text.tolist()):
            yield Event(f, self.kinds[k], r, self.texts[t] if t >= 0 else "", s)

    def of_kinds(self, kinds: "Sequence[str]") -> np.ndarray:
        """``(E,)`` whether each event is of one of ``kinds`` (shown names)."""
        return np.isin(self.kind, [i for i, k in enumerate(self.kinds) if k in set(kinds)])

    def label(self, index: int, robot_names: "Sequence[str] | None" = None) -> str:
        """One line of event ``index``: kind, robot, step and text."""
        kind, robot, step, text = self.kinds[self.kind[index]], int(self.robot[index]), int(self.step[index]), int(self.text[index])
        parts = [kind] + ([robot_names[robot] if robot_names else f"robot {robot}"] if robot >= 0 else [])
        detail = ", ".join(([f"step {step}"] if step >= 0 else []) + ([self.texts[text]] if text >= 0 else []))
        return " · ".join(parts + ([detail] if detail else []))

    def to_document(self) -> dict[str, Any]:
        return {"kinds": list(self.kinds), "texts": list(self.texts), "frame": encode_array(self.frame, "i4"),
                "kind": encode_array(self.kind, "i4"), "robot": encode_array(self.robot, "i4"),
                "step": encode_array(self.step, "i4"), "text": encode_array(self.text, "i4")}


@dataclass
class Scene:
    """A replay of one run (see the module docstring).

    Attributes
    ----------
    family, title, subtitle: what is replayed (the title names scenario, method and seed).
    steps: ``(F,)`` the simulation step of each frame (its recorded row × ``record_every``).
    times: ``(F,)`` simulated time of each frame, in ``time_unit``.
    events: the events on their frames (:class:`SceneEvents`; a list of :class:`Event` is turned into it).
    positions: ``(F, N, D)`` robot coordinates, ``D`` = 2 or 3.
    radius: drawn radius in length units (0: a point of ``point_px`` pixels).
    robot_colors: ``(N,)`` index into ``palette`` per robot.
    robot_names: a name per robot ("robot 3", "leader").
    status: ``(F, N)`` index into ``statuses`` (``{"name", "color" or None, "ring"}``).
    fields: values shown on hover.
    coordinates: further ``(F, N, 2)`` coordinate arrays a view can use as ``source``.
    trail: trail length in frames (0: no trails).
    notes: lines shown under the title (e.g. that frames were subsampled).
    solids: 3-D boxes (``center``, ``size``, ``yaw``) for viewers that draw in 3-D.
    """

    family: str
    title: str
    subtitle: str
    steps: np.ndarray
    times: np.ndarray
    positions: np.ndarray
    views: list[View]
    radius: float = 0.0
    point_px: float = 4.0
    time_unit: str = "s"
    length_unit: str = "m"
    palette: Sequence[str] = ROBOT_PALETTE
    robot_colors: np.ndarray | None = None
    robot_names: list[str] | None = None
    robot_markers: list[str] | None = None
    status: np.ndarray | None = None
    statuses: list[dict[str, Any]] = field(default_factory=list)
    fields: list[Field] = field(default_factory=list)
    coordinates: dict[str, np.ndarray] = field(default_factory=dict)
    shapes: list[Shape] = field(default_factory=list)
    layers: list[Layer] = field(default_factory=list)
    events: SceneEvents = field(default_factory=SceneEvents.empty)
    legend: list[dict[str, Any]] = field(default_factory=list)
    trail: int = 0
    notes: list[str] = field(default_factory=list)
    solids: list[dict[str, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.events = SceneEvents.of(self.events)

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_robots(self) -> int:
        return int(self.positions.shape[1])

    def robot_color_index(self) -> np.ndarray:
        """``(N,)`` palette index per robot (by robot index when none was set)."""
        if self.robot_colors is not None:
            return np.asarray(self.robot_colors, np.int64)
        return np.arange(self.n_robots) % len(self.palette)

    def robot_fill(self, frame: int, robot: int) -> str:
        """The colour robot ``robot`` is filled with at ``frame`` (its status's colour if
        that status has one, else its own)."""
        if self.status is not None:
            colour = self.statuses[int(self.status[frame, robot])].get("color")
            if colour:
                return colour
        return self.palette[int(self.robot_color_index()[robot])]

    def check(self) -> None:
        """Raise :class:`ConfigError` when the arrays disagree in shape."""
        F, N = self.n_frames, self.n_robots
        if self.positions.ndim != 3 or self.positions.shape[2] not in (2, 3):
            raise ConfigError(f"Scene: positions: expected shape (frames, robots, 2 or 3), received {self.positions.shape}")
        for name, array in (("steps", self.steps), ("times", self.times)):
            if np.shape(array) != (F,):
                raise ConfigError(f"Scene: {name}: expected shape ({F},), received {np.shape(array)}")
        if self.status is not None and np.shape(self.status) != (F, N):
            raise ConfigError(f"Scene: status: expected shape ({F}, {N}), received {np.shape(self.status)}")
        for f in self.fields:
            if np.shape(f.values) not in ((F, N), (F,)):
                raise ConfigError(f"Scene: field {f.name!r}: expected shape ({F}, {N}) or ({F},), received {np.shape(f.values)}")
        if len(self.events) and (self.events.frame.min() < 0 or self.events.frame.max() >= F):
            raise ConfigError(f"Scene: events: expected frames in [0, {F}), received {int(self.events.frame.min())}–{int(self.events.frame.max())}")
        for layer in self.layers:
            if "offsets" in layer.arrays and len(layer.arrays["offsets"]) != F + 1:
                raise ConfigError(f"Scene: layer {layer.group!r}: offsets: expected {F + 1} entries, received {len(layer.arrays['offsets'])}")

    def groups(self) -> list[str]:
        """The toggleable groups, in drawing order of first appearance."""
        names = [s.group for s in self.shapes] + [la.group for la in self.layers if not la.is_empty()]
        return list(dict.fromkeys(names))

    def to_document(self) -> dict[str, Any]:
        """The scene as a JSON-able dict, arrays encoded by :func:`encode_array`."""
        self.check()
        return {
            "version": SCENE_VERSION, "family": self.family, "title": self.title, "subtitle": self.subtitle,
            "n_frames": self.n_frames, "n_robots": self.n_robots, "dim": int(self.positions.shape[2]),
            "time_unit": self.time_unit, "length_unit": self.length_unit, "radius": float(self.radius),
            "point_px": float(self.point_px), "trail": int(self.trail), "palette": list(self.palette),
            "steps": encode_array(self.steps, "i4"), "times": encode_array(self.times, "f4"),
            "positions": encode_array(self.positions, "f4"),
            "coordinates": {k: encode_array(v, "f4") for k, v in self.coordinates.items()},
            "robot_colors": encode_array(self.robot_color_index(), "u1" if len(self.palette) < 256 else "i4"),
            "robot_names": self.robot_names or [f"robot {i}" for i in range(self.n_robots)],
            "robot_markers": self.robot_markers,
            "status": encode_array(self.status, "u1") if self.status is not None else None,
            "statuses": self.statuses,
            "fields": [{"name": f.name, "unit": f.unit, "labels": list(f.labels) if f.labels else None, "digits": f.digits,
                        "per_robot": np.ndim(f.values) == 2, "values": encode_array(f.values, "f4")} for f in self.fields],
            "views": [{"name": v.name, "axes": list(v.axes), "labels": list(v.labels), "lo": [float(x) for x in v.lo],
                       "hi": [float(x) for x in v.hi], "source": v.source} for v in self.views],
            "shapes": [{"kind": s.kind, "group": s.group, "points": np.asarray(s.points, float).round(6).tolist(),
                        "style": s.style, "view": s.view, "robot": s.robot, "text": s.text} for s in self.shapes],
            "layers": [{"kind": la.kind, "group": la.group, "style": la.style, "view": la.view,
                        "arrays": {k: encode_array(v, "i4" if np.asarray(v).dtype.kind in "biu" else "f4")
                                   for k, v in la.arrays.items()}}
                       for la in self.layers if not la.is_empty()],
            "events": self.events.to_document(),
            "groups": self.groups(), "legend": self.legend, "notes": self.notes,
        }


ENCODE_CHUNK_BYTES = 1 << 22
"""Bytes of an array converted and deflated at a time by :func:`encode_array`."""
DEFLATE_LEVEL = 1
"""zlib level of the page's arrays (byte planes deflate well at the fastest level)."""


def encode_array(array: Any, dtype: str) -> dict[str, Any]:
    """``{"dtype", "shape", "shuffle", "data"}``: the array as little-endian ``dtype``
    (``f4``, ``i4`` or ``u1``; non-finite floats become NaN), its bytes grouped by plane
    (every value's first byte, then every second byte, …: ``shuffle``, which lets floats
    deflate to about half), zlib-deflated and base64-encoded. Converted and deflated in
    chunks of :data:`ENCODE_CHUNK_BYTES` bytes, one plane at a time (no full-size copy)."""
    source = np.asarray(array)
    target = np.dtype(_DTYPES[dtype]).newbyteorder("<")
    flat = source.reshape(-1)
    width = target.itemsize
    step = max(1, ENCODE_CHUNK_BYTES // width)
    packer = zlib.compressobj(DEFLATE_LEVEL)
    packed = []
    for plane in range(width):
        for start in range(0, len(flat), step):
            values = np.ascontiguousarray(flat[start:start + step], dtype=target)
            packed.append(packer.compress(values.view(np.uint8)[plane::width].tobytes()))
    packed.append(packer.flush())
    return {"dtype": dtype, "shape": list(source.shape), "shuffle": True, "data": base64.b64encode(b"".join(packed)).decode("ascii")}


def decode_array(doc: dict[str, Any]) -> np.ndarray:
    """Inverse of :func:`encode_array`."""
    raw = np.frombuffer(zlib.decompress(base64.b64decode(doc["data"])), np.uint8)
    dtype = np.dtype(_DTYPES[doc["dtype"]]).newbyteorder("<")
    if doc.get("shuffle"):
        raw = np.ascontiguousarray(raw.reshape(dtype.itemsize, -1).T)
    return raw.view(dtype).reshape(doc["shape"])


def per_frame(items: Sequence[Sequence[Sequence[float]]], width: int) -> tuple[np.ndarray, np.ndarray]:
    """Offsets ``(F + 1,)`` and stacked rows ``(total, width)`` of per-frame row lists."""
    counts = np.array([len(rows) for rows in items], np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    rows = [np.asarray(r, float).reshape(-1, width) for r in items if len(r)]
    return offsets, (np.concatenate(rows) if rows else np.zeros((0, width)))


def frames_of_steps(steps: np.ndarray, frame_steps: np.ndarray) -> np.ndarray:
    """The first frame whose step is ≥ each step (clipped to the last frame): the frame
    covering it, frame ``f`` covering the steps after frame ``f − 1``'s up to its own."""
    return np.minimum(np.searchsorted(frame_steps, np.asarray(steps), side="left"), len(frame_steps) - 1)


def legend_entry(label: str, *, color: str, marker: str = "square", stroke: str | None = None, dash: bool = False) -> dict[str, Any]:
    """One legend row: a swatch (``marker`` in ``color``) and its label."""
    return {"label": label, "color": color, "marker": marker, "stroke": stroke or color, "dash": dash}
