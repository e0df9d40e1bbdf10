"""A scene as a recording for the Rerun viewer (``.rrd``; needs the ``rerun`` extra).

The same layers as the HTML page, on one time axis (``time``, the simulated time of each
frame): ``world/robots`` (3-D points for 3-D runs, else 2-D), the static shapes under
``world/<group>``, the per-frame layers under ``world/<group>`` (cells and ellipses as
closed line strips, arrows, marks and revealed points), robots of a view with its own
coordinates (the leader's frame) under ``<view>/robots``, the events as a text log under
``world/events``, and the 3-D obstacle boxes (``scene.solids``) under ``world/obstacles``.

Large scenes are sent in blocks of frames holding at most :data:`ITEMS_PER_BLOCK` items
(robots, cells, ellipses …) and :data:`EVENTS_PER_CHUNK` events at a time, so what is
built for the recording at once stays bounded whatever the number of robots and frames.
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path
from typing import Any

import numpy as np

from ...core.errors import ConfigError, one_line
from ...core.files import replacing
from .scene import Layer, Scene, Shape

TIME_AXIS = "time"
APPLICATION_ID = "robofleet"
"""The application id of every recording robofleet writes."""
RRD_MAGIC = b"RRF"
"""The first bytes of a Rerun recording file."""
STORE_INFO_WITHIN = 4096
"""Bytes from the start of a recording within which its application id is looked for."""


def _rerun():
    try:
        import rerun as rr
    except ImportError:
        raise ConfigError("--rerun: expected the rerun-sdk package (pip install 'robofleet[rerun]'), "
                          "received an environment without it") from None
    return rr


def entity_name(text: str) -> str:
    """An entity path part: lower case, words joined by ``_``."""
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_") or "layer"


def rgba(colour: str, alpha: float = 1.0) -> np.ndarray:
    """``#rrggbb`` → ``[r, g, b, a]`` (uint8)."""
    value = colour.lstrip("#")
    return np.array([int(value[k:k + 2], 16) for k in (0, 2, 4)] + [round(255 * alpha)], np.uint8)


ITEMS_PER_BLOCK = 1_000_000
"""Points (robot positions, marks, the corners of ellipses and cells) sent to the recording
in one call at most."""
ELLIPSE_SIDES = 24
"""Sides of the polygon an ellipse is drawn as."""
POLYGON_POINTS = 12
"""Points a cell is counted as when sizing the blocks of a ``polygons`` layer."""


def frame_blocks(counts: np.ndarray, limit: int | None = None) -> list[tuple[int, int]]:
    """Consecutive frame ranges ``[start, stop)`` whose items (``counts`` per frame) add up
    to at most ``limit`` (default :data:`ITEMS_PER_BLOCK`; one frame alone may have more)."""
    limit = ITEMS_PER_BLOCK if limit is None else limit
    blocks, start, total = [], 0, 0
    for frame, count in enumerate(np.asarray(counts, np.int64).tolist()):
        if frame > start and total + count > limit:
            blocks.append((start, frame))
            start, total = frame, 0
        total += count
    if start < len(counts):
        blocks.append((start, len(counts)))
    return blocks


def robot_colours(scene: Scene, start: int = 0, stop: int | None = None) -> np.ndarray:
    """``(F, N, 4)`` fill colour of every robot at frames ``start`` to ``stop`` (all by default)."""
    stop = scene.n_frames if stop is None else stop
    palette = np.stack([rgba(c) for c in scene.palette])
    colours = np.broadcast_to(palette[scene.robot_color_index()], (stop - start, scene.n_robots, 4)).copy()
    if scene.status is not None:
        status = scene.status[start:stop]
        for k, entry in enumerate(scene.statuses):
            if entry.get("color"):
                colours[status == k] = rgba(entry["color"])
    return colours


def write_rrd(scene: Scene, path: str | Path) -> Path:
    """Write ``scene`` as a Rerun recording to ``path`` (the file replaced only once
    complete, :func:`~robofleet.core.files.replacing`); return the path.

    Raises
    ------
    ConfigError
        The ``rerun`` extra is not installed, or ``path`` cannot be written.
    """
    rr = _rerun()
    path = Path(path)
    scene.check()
    try:
        with replacing(path) as temp:
            rec = rr.RecordingStream(APPLICATION_ID, recording_id=f"{scene.family}-{entity_name(scene.title)}", send_properties=False)
            try:
                rec.save(temp)
            except RuntimeError as exc:
                raise OSError(one_line(exc)) from None
            log_scene(rr, rec, scene)
            rec.flush()
            rec.disconnect()
    except OSError as exc:
        raise ConfigError(f"--rerun: expected a writable file path, received {path} ({exc.strerror or one_line(exc)})") from None
    return path


def log_scene(rr: Any, rec: Any, scene: Scene) -> None:
    """Log every layer of ``scene`` to the recording ``rec``."""
    times = np.asarray(scene.times, float)
    rec.log("world", rr.TextDocument(f"{scene.title}\n\n{scene.subtitle}"), static=True)
    log_robots(rr, rec, scene, times)
    for index, shape in enumerate(scene.shapes):
        log_shape(rr, rec, scene, shape, index)
    for layer in scene.layers:
        if not layer.is_empty():
            log_layer(rr, rec, scene, layer, times)
    log_solids(rr, rec, scene)
    log_events(rr, rec, scene)


def is_robofleet_recording(path: str | Path) -> bool:
    """Whether the file at ``path`` is a Rerun recording robofleet wrote: it starts with
    :data:`RRD_MAGIC` and names :data:`APPLICATION_ID` in its first message (the store
    info, read without the rerun extra)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(STORE_INFO_WITHIN)
    except OSError:
        return False
    return head.startswith(RRD_MAGIC) and APPLICATION_ID.encode() in head


def view_root(scene: Scene, view: int) -> str:
    """``world`` for the main view (and the side view of a 3-D scene, which is in the 3-D
    world already), else the view's own entity."""
    if view == 0 or scene.positions.shape[2] == 3:
        return "world"
    return entity_name(scene.views[view].name.split("(")[0])


def time_column(rr: Any, times: np.ndarray, start: int, stop: int) -> Any:
    """The time axis of frames ``start`` to ``stop``."""
    return rr.TimeColumn(TIME_AXIS, duration=times[start:stop])


def log_robots(rr: Any, rec: Any, scene: Scene, times: np.ndarray) -> None:
    F, N, D = scene.positions.shape
    names = scene.robot_names or [f"robot {i}" for i in range(N)]
    radius = scene.radius if scene.radius > 0 else 1.0
    archetype = rr.Points3D if D == 3 else rr.Points2D
    rec.log("world/robots", archetype.from_fields(labels=names, radii=np.full(N, radius, np.float32)), static=True)
    others = [(v, view) for v, view in enumerate(scene.views) if view.source != "positions" and view.source in scene.coordinates]
    for v, _ in others:
        rec.log(f"{view_root(scene, v)}/robots", rr.Points2D.from_fields(labels=names, radii=np.full(N, radius, np.float32)), static=True)
    for start, stop in frame_blocks(np.full(F, N)):
        colours = robot_colours(scene, start, stop).reshape(-1, 4)
        columns = archetype.columns(positions=scene.positions[start:stop].reshape(-1, D), colors=colours)
        rec.send_columns("world/robots", indexes=[time_column(rr, times, start, stop)], columns=columns.partition(np.full(stop - start, N)))
        for v, view in others:
            xy = scene.coordinates[view.source][start:stop][..., list(view.axes)].reshape(-1, 2)
            rec.send_columns(f"{view_root(scene, v)}/robots", indexes=[time_column(rr, times, start, stop)],
                             columns=rr.Points2D.columns(positions=xy, colors=colours).partition(np.full(stop - start, N)))


def _in_world(scene: Scene, view: int, points: np.ndarray) -> np.ndarray:
    """View coordinates as world coordinates: 3-D scenes put the top view at z = 0 and the
    side view (x, z) at y = 0; 2-D scenes keep them."""
    points = np.asarray(points, float).reshape(-1, 2)
    if scene.positions.shape[2] != 3:
        return points
    out = np.zeros((len(points), 3))
    axes = scene.views[view].axes
    out[:, axes[0]], out[:, axes[1]] = points[:, 0], points[:, 1]
    return out


def _style_colour(scene: Scene, style: dict, key: str, robot: int) -> np.ndarray:
    value = style.get(key) or style.get("stroke") or style.get("fill") or "#444444"
    if value == "robot":
        value = scene.palette[int(scene.robot_color_index()[robot])] if robot >= 0 else "#444444"
    return rgba(value, float(style.get("alpha", 1.0)) if key == "fill" else 1.0)


def log_shape(rr: Any, rec: Any, scene: Scene, shape: Shape, index: int) -> None:
    if scene.positions.shape[2] == 3 and shape.view != 0 and shape.group == "obstacles":
        return  # the side view's box outlines: the boxes themselves are logged in 3-D
    entity = f"{view_root(scene, shape.view)}/{entity_name(shape.group)}"
    pts = _in_world(scene, shape.view, shape.points)
    three_d = pts.shape[1] == 3
    colour = _style_colour(scene, shape.style, "stroke", shape.robot)
    if shape.kind in ("polygon", "polyline"):
        strip = np.vstack([pts, pts[:1]]) if shape.kind == "polygon" else pts
        archetype = rr.LineStrips3D if three_d else rr.LineStrips2D
        rec.log(f"{entity}/{index}", archetype([strip], colors=[colour]), static=True)
    elif shape.kind in ("points", "text"):
        archetype = rr.Points3D if three_d else rr.Points2D
        labels = [shape.text] * len(pts) if shape.text else None
        rec.log(f"{entity}/{index}", archetype(pts, colors=[colour], labels=labels), static=True)


def log_layer(rr: Any, rec: Any, scene: Scene, layer: Layer, times: np.ndarray) -> None:
    """A per-frame layer, in blocks of frames (:func:`frame_blocks`)."""
    entity = f"{view_root(scene, layer.view)}/{entity_name(layer.group)}"
    a, F = layer.arrays, scene.n_frames
    if layer.kind == "reveal":
        first = np.where(a["frame"] >= 0, a["frame"], F)
        shown = np.array([int((first <= f).sum()) for f in range(F)])
        order = np.argsort(first, kind="stable")
        for start, stop in frame_blocks(shown):
            pts = np.concatenate([_in_world(scene, layer.view, a["xy"][order[:shown[f]]]) for f in range(start, stop)])
            archetype = rr.Points3D if pts.shape[1] == 3 else rr.Points2D
            rec.send_columns(entity, indexes=[time_column(rr, times, start, stop)],
                             columns=archetype.columns(positions=pts).partition(shown[start:stop]))
        return
    offsets = np.asarray(a["offsets"], np.int64)
    counts = np.diff(offsets)
    points = ELLIPSE_SIDES + 1 if layer.kind == "ellipses" else POLYGON_POINTS if layer.kind == "polygons" else 1
    for start, stop in frame_blocks(counts, ITEMS_PER_BLOCK // points):
        lo, hi = int(offsets[start]), int(offsets[stop])
        columns = layer_columns(rr, scene, layer, lo, hi, np.repeat(np.arange(start, stop), counts[start:stop]))
        rec.send_columns(entity, indexes=[time_column(rr, times, start, stop)], columns=columns.partition(counts[start:stop]))


def layer_columns(rr: Any, scene: Scene, layer: Layer, lo: int, hi: int, frame_of_item: np.ndarray) -> Any:
    """The columns of the layer's items ``lo`` to ``hi`` (at frames ``frame_of_item``)."""
    a = layer.arrays
    robots = a["robot"][lo:hi] if a.get("robot") is not None else None
    colours = item_colours(scene, layer.style, robots) if robots is not None and len(robots) else None
    lifted = scene.positions.shape[2] == 3 and robots is not None and layer.kind in ("segments", "marks")
    if lifted:  # a 3-D scene's projected marks and headings start at their robot's 3-D position
        anchor = scene.positions[frame_of_item, robots]
    if layer.kind == "segments" and lifted:
        xy = a["xy"][lo:hi]
        tips = np.concatenate([xy[:, 2:] - xy[:, :2], np.zeros((len(robots), 1))], axis=1)
        return rr.Arrows3D.columns(origins=anchor, vectors=tips, colors=colours)
    if layer.kind == "marks" and lifted:
        return rr.Points3D.columns(positions=anchor, colors=colours)
    if layer.kind == "segments":
        xy = a["xy"][lo:hi]
        start, end = _in_world(scene, layer.view, xy[:, :2]), _in_world(scene, layer.view, xy[:, 2:])
        archetype = rr.Arrows3D if start.shape[1] == 3 else rr.Arrows2D
        return archetype.columns(origins=start, vectors=end - start, colors=colours)
    if layer.kind == "marks":
        pts = _in_world(scene, layer.view, a["xy"][lo:hi])
        archetype = rr.Points3D if pts.shape[1] == 3 else rr.Points2D
        return archetype.columns(positions=pts, colors=colours)
    strips = polygon_strips(layer, lo, hi) if layer.kind == "polygons" else ellipse_strips(layer, lo, hi)
    three_d = scene.positions.shape[2] == 3
    if three_d or layer.kind == "polygons":
        strips = [_in_world(scene, layer.view, s) for s in strips]
    return (rr.LineStrips3D if three_d else rr.LineStrips2D).columns(strips=strips, colors=colours)


def item_colours(scene: Scene, style: dict, robots: np.ndarray) -> np.ndarray:
    """``(k, 4)`` the stroke colour of items of ``robots`` (one colour per distinct robot computed)."""
    unique, inverse = np.unique(robots, return_inverse=True)
    return np.stack([_style_colour(scene, style, "stroke", int(r)) for r in unique])[inverse.reshape(-1)]


def polygon_strips(layer: Layer, lo: int = 0, hi: int | None = None) -> list[np.ndarray]:
    """Closed outlines of polygons ``lo`` to ``hi`` of a ``polygons`` layer, in its polygon order."""
    bounds, vertices = layer.arrays["polygon"], layer.arrays["vertices"]
    hi = len(bounds) - 1 if hi is None else hi
    return [np.vstack([vertices[s:e], vertices[s:s + 1]]) for s, e in itertools.pairwise(bounds[lo:hi + 1])]


def ellipse_strips(layer: Layer, lo: int = 0, hi: int | None = None, sides: int | None = None) -> np.ndarray:
    """``(E, sides + 1, 2)``: closed polygons (24-gons by default) of ellipses ``lo`` to
    ``hi`` of an ``ellipses`` layer, computed together."""
    sides = ELLIPSE_SIDES if sides is None else sides
    xy, shape = layer.arrays["xy"][lo:hi], layer.arrays["shape"][lo:hi]
    t = np.linspace(0.0, 2 * np.pi, sides + 1)
    c, s = np.cos(shape[:, 2:3]), np.sin(shape[:, 2:3])
    u, v = 0.5 * shape[:, 0:1] * np.cos(t), 0.5 * shape[:, 1:2] * np.sin(t)
    return np.stack([xy[:, 0:1] + c * u - s * v, xy[:, 1:2] + s * u + c * v], axis=-1)


def log_solids(rr: Any, rec: Any, scene: Scene) -> None:
    if not scene.solids:
        return
    centres = np.array([s["center"] for s in scene.solids], float)
    half = 0.5 * np.array([s["size"] for s in scene.solids], float)
    rotations = [rr.RotationAxisAngle(axis=[0, 0, 1], radians=float(s.get("yaw", 0.0))) for s in scene.solids]
    rec.log("world/obstacles/boxes", rr.Boxes3D(centers=centres, half_sizes=half, rotation_axis_angles=rotations,
                                                colors=[rgba("#808080")], fill_mode="solid"), static=True)


EVENTS_PER_CHUNK = 50_000
"""Events logged per call (their texts made for one chunk at a time)."""


def log_events(rr: Any, rec: Any, scene: Scene) -> None:
    """The events as a text log at their frames' times, :data:`EVENTS_PER_CHUNK` at a time."""
    events = scene.events
    names = scene.robot_names or [f"robot {i}" for i in range(scene.n_robots)]
    times = np.asarray(scene.times, float)
    for start in range(0, len(events), EVENTS_PER_CHUNK):
        chunk = range(start, min(len(events), start + EVENTS_PER_CHUNK))
        texts = [events.label(i, names) for i in chunk]
        column = rr.TimeColumn(TIME_AXIS, duration=times[events.frame[chunk.start:chunk.stop]])
        rec.send_columns("world/events", indexes=[column], columns=rr.TextLog.columns(text=texts))
