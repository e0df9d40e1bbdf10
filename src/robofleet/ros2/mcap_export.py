"""``robofleet export RUN --mcap FILE.mcap``: a recorded run as ROS 2 messages in an MCAP
file (profile ``ros2``, CDR messages with ``ros2msg`` schemas, as ``ros2 bag record``
writes them), which Foxglove and ``ros2 bag`` read.

Topics, one message per recorded step ``k`` at time ``k · dt`` (the robot namespaces as
the nodes use them):

* avoidance runs: ``<ns>/pose`` (``PoseWithCovarianceStamped``: the estimate the robot
  used, with its covariance), ``<ns>/ground_truth`` (``PoseStamped``: the true position),
  ``<ns>/goal`` (``PoseStamped``, once), and, when the run recorded cells,
  ``<ns>/cell`` (``PolygonStamped``) and all cells on ``/robofleet/cells``
  (``MarkerArray``);
* coordination runs: ``<ns>/pose`` (the position on the plan), ``<ns>/progress``
  (``Int32``) and ``<ns>/plan`` (``Path``, the whole plan, once);
* other families: ``<ns>/ground_truth`` of the recorded positions.

The messages are the nodes' own (:mod:`.messages`), serialized by rclpy; each schema is
the message definition written out from the message class (fields and nested types).
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ..core.errors import ConfigError
from ..core.files import replacing
from ..core.trace import Trace
from .messages import cell_markers, goal_message, int_message, path_message, polygon_message, pose_message
from .runtime import CELLS_TOPIC, DEFAULT_PREFIX, MAP_FRAME, robot_topic

SEPARATOR = "=" * 80
PRIMITIVES = {"boolean": "bool", "octet": "byte", "double": "float64", "float": "float32"}
"""IDL names of primitive types that a .msg file spells differently."""


# -- schemas ---------------------------------------------------------------------------------
def message_class(name: str) -> type:
    """The class of ``geometry_msgs/Pose`` (or ``geometry_msgs/msg/Pose``)."""
    package, *_, kind = name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), kind)


def field_type(idl: str) -> tuple[str, str | None]:
    """A field type as written in a ``.msg`` file, and the nested message it names (if any)."""
    match = re.fullmatch(r"sequence<([^,>]+)(?:,\s*(\d+))?>", idl)
    if match:
        inner, nested = field_type(match.group(1))
        return (f"{inner}[<={match.group(2)}]" if match.group(2) else f"{inner}[]"), nested
    match = re.fullmatch(r"(.+)\[(\d+)\]", idl)
    if match:
        inner, nested = field_type(match.group(1))
        return f"{inner}[{match.group(2)}]", nested
    match = re.fullmatch(r"(w?string)<(\d+)>", idl)
    if match:
        return f"{match.group(1)}<={match.group(2)}", None
    if "/" in idl:
        return idl, idl
    return PRIMITIVES.get(idl, idl), None


def definition(cls: type) -> tuple[str, list[str]]:
    """The ``.msg`` text of a message class and the nested types it uses."""
    lines, nested = [], []
    for name, idl in cls.get_fields_and_field_types().items():
        text, inner = field_type(idl)
        lines.append(f"{text} {name}")
        if inner is not None:
            nested.append(inner)
    return "\n".join(lines) + "\n", nested


def schema_text(name: str) -> str:
    """The full ``ros2msg`` schema: the type's definition, then each nested type's once
    (``MSG: package/Type`` headers), depth first."""
    text, pending = definition(message_class(name))
    parts, seen = [text], set()
    while pending:
        inner = pending.pop(0)
        if inner in seen:
            continue
        seen.add(inner)
        body, more = definition(message_class(inner))
        parts.append(f"{SEPARATOR}\nMSG: {inner}\n{body}")
        pending.extend(more)
    return "\n".join(parts)


def ros_type_name(message: Any) -> str:
    """``geometry_msgs/msg/PoseStamped`` of a message instance."""
    module = type(message).__module__.split(".")[0]
    return f"{module}/msg/{type(message).__name__}"


# -- what a run becomes --------------------------------------------------------------------
def run_messages(trace: Trace, prefix: str = DEFAULT_PREFIX) -> Iterator[tuple[str, float, Any]]:
    """``(topic, time [s], message)`` of a run, in time order."""
    md = trace.metadata
    dt = float(md.get("dt", 1.0))
    every = trace.record_every
    positions = trace.positions
    n = positions.shape[1]
    if positions.shape[-1] != 2:
        raise ConfigError(f"RUN: expected a 2-D run, received positions of dimension {positions.shape[-1]}")
    if trace.family == "avoidance":
        yield from avoidance_messages(trace, prefix, dt, every)
        return
    if trace.family == "coordination" and "plan" in trace.arrays:
        plan = np.asarray(trace.arrays["plan"], float)
        for i in range(n):
            yield robot_topic(prefix, i, "plan"), 0.0, path_message(plan[:, i], 0.0, MAP_FRAME)
    progress = trace.arrays.get("progress")
    for k in range(len(positions)):
        t = k * every * dt
        for i in range(n):
            if trace.family == "coordination":
                yield robot_topic(prefix, i, "pose"), t, pose_message(positions[k, i], np.zeros((2, 2)), t, MAP_FRAME)
                if progress is not None:
                    yield robot_topic(prefix, i, "progress"), t, int_message(int(np.asarray(progress)[k, i].reshape(-1)[0]))
            else:
                yield robot_topic(prefix, i, "ground_truth"), t, goal_message(positions[k, i], t, MAP_FRAME)


def robot_covariances(trace: Trace, n: int) -> np.ndarray:
    """``(n, 2, 2)`` estimate covariances of an avoidance run (zeros when unknown)."""
    md = trace.metadata
    if md.get("robot_covs") is not None:
        return np.asarray(md["robot_covs"], float).reshape(n, 2, 2)
    if md.get("robot_cov") is not None:
        return np.broadcast_to(np.asarray(md["robot_cov"], float), (n, 2, 2))
    sigma = np.asarray(md.get("sigma", 0.0), float)
    return np.broadcast_to(sigma.reshape(-1, 1, 1) ** 2 * np.eye(2), (n, 2, 2))


def avoidance_messages(trace: Trace, prefix: str, dt: float, every: int) -> Iterator[tuple[str, float, Any]]:
    positions = trace.positions
    n = positions.shape[1]
    estimates = trace.arrays.get("estimates")
    covs = robot_covariances(trace, n)
    headings = trace.arrays.get("headings")
    cells = (trace.arrays["cell_A"], trace.arrays["cell_b"]) if "cell_A" in trace.arrays and "cell_b" in trace.arrays else None
    for i, goal in enumerate(np.asarray(trace.metadata.get("goals", []), float)):
        yield robot_topic(prefix, i, "goal"), 0.0, goal_message(goal, 0.0, MAP_FRAME)
    clip = cell_clip(trace)
    for k in range(len(positions)):
        t = k * every * dt
        yaw = np.nan_to_num(headings[k]) if headings is not None else np.zeros(n)
        for i in range(n):
            yield robot_topic(prefix, i, "ground_truth"), t, goal_message(positions[k, i], t, MAP_FRAME)
        if estimates is not None and k < len(estimates):
            for i in range(n):
                yield robot_topic(prefix, i, "pose"), t, pose_message(estimates[k, i], covs[i], t, MAP_FRAME, float(yaw[i]))
        if cells is not None and k < len(cells[0]):
            polygons = {i: cell_polygon_of(cells[0][k, i], cells[1][k, i], clip) for i in range(n)}
            for i, vertices in polygons.items():
                yield robot_topic(prefix, i, "cell"), t, polygon_message(vertices, t, MAP_FRAME)
            yield CELLS_TOPIC, t, cell_markers(polygons, t, MAP_FRAME, lifetime=every * dt)


def cell_clip(trace: Trace) -> np.ndarray:
    from ..viz.avoidance import clip_region

    return clip_region(trace)


def cell_polygon_of(A: np.ndarray, b: np.ndarray, clip: np.ndarray) -> np.ndarray:
    from ..viz.avoidance import cell_polygon

    return cell_polygon(A, b, clip)


# -- the file --------------------------------------------------------------------------------
def export_mcap(run: str | Path, out: str | Path, prefix: str = DEFAULT_PREFIX) -> tuple[Path, int]:
    """Write the run in ``run`` (a directory with trace.npz/trace.json) to ``out``;
    returns the path and the number of messages. The file is written whole
    (:func:`robofleet.core.files.replacing`)."""
    from mcap.writer import Writer
    from rclpy.serialization import serialize_message

    out = Path(out)
    if out.suffix != ".mcap":
        raise ConfigError(f"--mcap: expected a FILE.mcap, received {out}")
    if out.is_dir():
        raise ConfigError(f"--mcap: expected a file path, received the directory {out}")
    trace = Trace.load(run)
    count = 0
    try:
        with replacing(out) as temp, open(temp, "wb") as stream:
            writer = Writer(stream)
            writer.start(profile="ros2", library="robofleet")
            schemas: dict[str, int] = {}
            channels: dict[str, int] = {}
            for topic, t, message in run_messages(trace, prefix):
                kind = ros_type_name(message)
                if kind not in schemas:
                    schemas[kind] = writer.register_schema(name=kind, encoding="ros2msg", data=schema_text(kind).encode())
                if topic not in channels:
                    channels[topic] = writer.register_channel(topic=topic, message_encoding="cdr", schema_id=schemas[kind])
                ns = int(round(t * 1e9))
                writer.add_message(channels[topic], log_time=ns, data=serialize_message(message), publish_time=ns, sequence=count)
                count += 1
            writer.finish()
    except OSError as exc:
        raise ConfigError(f"--mcap: expected a writable file, received {out} ({exc.strerror})") from None
    return out, count
