"""A scene as a recording for the Rerun viewer (``.rrd``; needs the ``rerun`` extra).

The same layers as the HTML page, on one time axis (``time``, the simulated time of each
frame): ``world/robots`` (3-D points for 3-D runs, else 2-D), the static shapes under
``world/<group>``, the per-frame layers under ``world/<group>`` (cells and ellipses as
closed line strips, arrows, marks and revealed points), robots of a view with its own
coordinates (the leader's frame) under ``<view>/robots``, the events as a text log under
``world/events``, and the 3-D obstacle boxes (``scene.solids``) under ``world/obstacles``.
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


def robot_colours(scene: Scene) -> np.ndarray:
    """``(F, N, 4)`` fill colour of every robot at every frame."""
    palette = np.stack([rgba(c) for c in scene.palette])
    colours = np.broadcast_to(palette[scene.robot_color_index()], (scene.n_frames, scene.n_robots, 4)).copy()
    if scene.status is not None:
        for k, status in enumerate(scene.statuses):
            if status.get("color"):
                colours[scene.status == k] = rgba(status["color"])
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
    times = rr.TimeColumn(TIME_AXIS, duration=np.asarray(scene.times, float))
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


def log_robots(rr: Any, rec: Any, scene: Scene, times: Any) -> None:
    F, N, D = scene.positions.shape
    names = scene.robot_names or [f"robot {i}" for i in range(N)]
    radius = scene.radius if scene.radius > 0 else 1.0
    colours = robot_colours(scene).reshape(-1, 4)
    archetype = rr.Points3D if D == 3 else rr.Points2D
    rec.log("world/robots", archetype.from_fields(labels=names, radii=np.full(N, radius, np.float32)), static=True)
    columns = archetype.columns(positions=scene.positions.reshape(-1, D), colors=colours)
    rec.send_columns("world/robots", indexes=[times], columns=columns.partition(np.full(F, N)))
    for v, view in enumerate(scene.views):
        if view.source != "positions" and view.source in scene.coordinates:
            root = view_root(scene, v)
            rec.log(f"{root}/robots", rr.Points2D.from_fields(labels=names, radii=np.full(N, radius, np.float32)), static=True)
            xy = scene.coordinates[view.source][..., list(view.axes)].reshape(-1, 2)
            rec.send_columns(f"{root}/robots", indexes=[times], columns=rr.Points2D.columns(positions=xy, colors=colours).partition(np.full(F, N)))


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


def log_layer(rr: Any, rec: Any, scene: Scene, layer: Layer, times: Any) -> None:
    entity = f"{view_root(scene, layer.view)}/{entity_name(layer.group)}"
    a, F = layer.arrays, scene.n_frames
    robots = a.get("robot")
    if layer.kind == "reveal":
        visible = [(a["frame"] >= 0) & (a["frame"] <= f) for f in range(F)]
        pts = np.concatenate([_in_world(scene, layer.view, a["xy"][m]) for m in visible])
        archetype = rr.Points3D if pts.shape[1] == 3 else rr.Points2D
        rec.send_columns(entity, indexes=[times], columns=archetype.columns(positions=pts).partition([int(m.sum()) for m in visible]))
        return
    counts = np.diff(np.asarray(a["offsets"], np.int64))
    frame_of_item = np.repeat(np.arange(F), counts)
    colours = np.stack([_style_colour(scene, layer.style, "stroke", int(r)) for r in robots]) if robots is not None and len(robots) else None
    lifted = scene.positions.shape[2] == 3 and robots is not None and layer.kind in ("segments", "marks")
    if lifted:  # a 3-D scene's projected marks and headings start at their robot's 3-D position
        anchor = scene.positions[frame_of_item, robots]
    if layer.kind == "segments" and lifted:
        tips = np.concatenate([a["xy"][:, 2:] - a["xy"][:, :2], np.zeros((len(robots), 1))], axis=1)
        columns = rr.Arrows3D.columns(origins=anchor, vectors=tips, colors=colours)
    elif layer.kind == "marks" and lifted:
        columns = rr.Points3D.columns(positions=anchor, colors=colours)
    elif layer.kind == "segments":
        start, end = _in_world(scene, layer.view, a["xy"][:, :2]), _in_world(scene, layer.view, a["xy"][:, 2:])
        archetype = rr.Arrows3D if start.shape[1] == 3 else rr.Arrows2D
        columns = archetype.columns(origins=start, vectors=end - start, colors=colours)
    elif layer.kind == "marks":
        pts = _in_world(scene, layer.view, a["xy"])
        archetype = rr.Points3D if pts.shape[1] == 3 else rr.Points2D
        columns = archetype.columns(positions=pts, colors=colours)
    else:
        strips = polygon_strips(layer) if layer.kind == "polygons" else ellipse_strips(layer)
        strips = [_in_world(scene, layer.view, s) for s in strips]
        archetype = rr.LineStrips3D if strips and strips[0].shape[1] == 3 else rr.LineStrips2D
        columns = archetype.columns(strips=strips, colors=colours)
    rec.send_columns(entity, indexes=[times], columns=columns.partition(counts))


def polygon_strips(layer: Layer) -> list[np.ndarray]:
    """Closed outlines of a ``polygons`` layer, in its polygon order."""
    bounds, vertices = layer.arrays["polygon"], layer.arrays["vertices"]
    return [np.vstack([vertices[s:e], vertices[s:s + 1]]) for s, e in itertools.pairwise(bounds)]


def ellipse_strips(layer: Layer, sides: int = 24) -> list[np.ndarray]:
    """Closed 24-gons of an ``ellipses`` layer."""
    t = np.linspace(0.0, 2 * np.pi, sides + 1)
    out = []
    for (x, y), (w, h, angle) in zip(layer.arrays["xy"], layer.arrays["shape"]):
        c, s = np.cos(angle), np.sin(angle)
        u, v = 0.5 * w * np.cos(t), 0.5 * h * np.sin(t)
        out.append(np.stack([x + c * u - s * v, y + s * u + c * v], axis=1))
    return out


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
