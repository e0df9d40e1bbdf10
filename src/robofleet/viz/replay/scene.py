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
    robot) or ``(n_frames,)`` (the team's); ``labels`` names integer codes, if any."""

    name: str
    values: np.ndarray
    unit: str = ""
    labels: Sequence[str] | None = None
    digits: int = 3


@dataclass
class Event:
    """Something that happened at a frame (``robot = -1``: no single robot)."""

    frame: int
    kind: str
    robot: int = -1
    text: str = ""


@dataclass
class Scene:
    """A replay of one run (see the module docstring).

    Attributes
    ----------
    family, title, subtitle: what is replayed (the title names scenario, method and seed).
    steps: ``(F,)`` the recorded state index of each frame.
    times: ``(F,)`` simulated time of each frame, in ``time_unit``.
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
    events: list[Event] = field(default_factory=list)
    legend: list[dict[str, Any]] = field(default_factory=list)
    trail: int = 0
    notes: list[str] = field(default_factory=list)
    solids: list[dict[str, Any]] = field(default_factory=list)

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
            "events": [{"frame": e.frame, "kind": e.kind, "robot": e.robot, "text": e.text} for e in self.events],
            "groups": self.groups(), "legend": self.legend, "notes": self.notes,
        }


def encode_array(array: Any, dtype: str) -> dict[str, Any]:
    """``{"dtype", "shape", "data"}``: the array as little-endian ``dtype`` (``f4``,
    ``i4`` or ``u1``), zlib-deflated and base64-encoded (non-finite floats become NaN)."""
    values = np.ascontiguousarray(np.asarray(array), dtype=np.dtype(_DTYPES[dtype]).newbyteorder("<"))
    packed = zlib.compress(values.tobytes(), 6)
    return {"dtype": dtype, "shape": list(values.shape), "data": base64.b64encode(packed).decode("ascii")}


def decode_array(doc: dict[str, Any]) -> np.ndarray:
    """Inverse of :func:`encode_array`."""
    raw = zlib.decompress(base64.b64decode(doc["data"]))
    return np.frombuffer(raw, dtype=np.dtype(_DTYPES[doc["dtype"]]).newbyteorder("<")).reshape(doc["shape"])


def per_frame(items: Sequence[Sequence[Sequence[float]]], width: int) -> tuple[np.ndarray, np.ndarray]:
    """Offsets ``(F + 1,)`` and stacked rows ``(total, width)`` of per-frame row lists."""
    counts = np.array([len(rows) for rows in items], np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    rows = [np.asarray(r, float).reshape(-1, width) for r in items if len(r)]
    return offsets, (np.concatenate(rows) if rows else np.zeros((0, width)))


def frames_of_steps(steps: np.ndarray, frame_steps: np.ndarray) -> np.ndarray:
    """The first frame whose state index is ≥ each step (clipped to the last frame)."""
    return np.minimum(np.searchsorted(frame_steps, np.asarray(steps), side="left"), len(frame_steps) - 1)


def legend_entry(label: str, *, color: str, marker: str = "square", stroke: str | None = None, dash: bool = False) -> dict[str, Any]:
    """One legend row: a swatch (``marker`` in ``color``) and its label."""
    return {"label": label, "color": color, "marker": marker, "stroke": stroke or color, "dash": dash}
