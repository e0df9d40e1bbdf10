"""Conversions between robofleet's arrays and ROS 2 messages, and the checks of what
arrives (one place for both).

Poses: ``geometry_msgs/PoseWithCovarianceStamped`` in the ``map`` frame; the x–y block of
the 6×6 row-major covariance (entries 0, 1, 6, 7) is the estimate's ``Σ``, the heading
is the yaw of the orientation. Velocities: ``geometry_msgs/Twist``, ``linear.x/y`` (map
frame, or the robot's base frame rotated by its yaw), ``angular.z`` for a
differential-drive robot. A message that cannot be used raises :class:`MessageError`
with one line saying what was expected and what was received; the nodes log that line
and ignore the message.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..core.errors import RobofleetError, short_repr

COV_XY = (0, 1, 6, 7)
"""Indices of the x–y block in a row-major 6×6 pose covariance."""


class MessageError(RobofleetError, ValueError):
    """A received message that cannot be used (the node logs it and goes on)."""


# -- time ------------------------------------------------------------------------------------
def stamp_of(seconds: float):
    """``builtin_interfaces/Time`` of a time in seconds."""
    from builtin_interfaces.msg import Time

    sec = math.floor(seconds)
    return Time(sec=int(sec), nanosec=min(int(round((seconds - sec) * 1e9)), 999_999_999))


def seconds_of(stamp) -> float:
    """Seconds of a ``builtin_interfaces/Time``."""
    return stamp.sec + stamp.nanosec * 1e-9


# -- poses -----------------------------------------------------------------------------------
def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """``(x, y, z, w)`` of a rotation by ``yaw`` about z."""
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)


def yaw_of(q) -> float:
    """The yaw of a quaternion message (its rotation about z)."""
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def pose_message(position: np.ndarray, cov: np.ndarray, seconds: float, frame: str, yaw: float = 0.0):
    """A ``PoseWithCovarianceStamped`` at ``position (2,)`` with x–y covariance ``cov (2, 2)``."""
    from geometry_msgs.msg import PoseWithCovarianceStamped

    msg = PoseWithCovarianceStamped()
    msg.header.stamp, msg.header.frame_id = stamp_of(seconds), frame
    msg.pose.pose.position.x, msg.pose.pose.position.y = float(position[0]), float(position[1])
    q = msg.pose.pose.orientation
    q.x, q.y, q.z, q.w = yaw_quaternion(yaw)
    full = np.zeros(36)
    full[list(COV_XY)] = np.asarray(cov, float).reshape(4)
    msg.pose.covariance = full
    return msg


def read_pose(msg, frame: str) -> tuple[np.ndarray, np.ndarray, float, float]:
    """``(position (2,), cov (2, 2), stamp seconds, yaw)`` of a ``PoseWithCovarianceStamped``.

    Raises :class:`MessageError` for another frame, non-finite numbers, or an x–y
    covariance block that is not symmetric positive semi-definite.
    """
    if msg.header.frame_id != frame:
        raise MessageError(f"header.frame_id: expected {frame!r}, received {msg.header.frame_id!r}")
    p = msg.pose.pose.position
    position = np.array([p.x, p.y], float)
    if not np.all(np.isfinite(position)):
        raise MessageError(f"pose.position: expected finite x, y, received {position.tolist()}")
    q = msg.pose.pose.orientation
    if not all(math.isfinite(v) for v in (q.x, q.y, q.z, q.w)) or q.x == q.y == q.z == q.w == 0.0:
        raise MessageError(f"pose.orientation: expected a finite, non-zero quaternion, received {[q.x, q.y, q.z, q.w]}")
    cov = np.asarray(msg.pose.covariance, float)[list(COV_XY)].reshape(2, 2)
    check_covariance_block(cov)
    return position, cov, seconds_of(msg.header.stamp), yaw_of(q)


def check_covariance_block(cov: np.ndarray) -> None:
    """A finite, symmetric, positive semi-definite ``(2, 2)`` block, else :class:`MessageError`."""
    scale = max(float(np.max(np.abs(cov))), 1e-300) if np.all(np.isfinite(cov)) else np.nan
    if not np.isfinite(scale) or abs(cov[0, 1] - cov[1, 0]) > 1e-9 * scale or np.linalg.eigvalsh(cov).min() < -1e-9 * scale:
        raise MessageError(f"pose.covariance: expected a symmetric positive semi-definite x-y block, received {cov.tolist()}")


# -- velocities ------------------------------------------------------------------------------
def twist_message(linear: Sequence[float], angular_z: float = 0.0):
    """A ``Twist`` with ``linear.x, linear.y`` and ``angular.z``."""
    from geometry_msgs.msg import Twist

    msg = Twist()
    msg.linear.x, msg.linear.y, msg.angular.z = float(linear[0]), float(linear[1]), float(angular_z)
    return msg


def read_twist(msg) -> tuple[np.ndarray, float]:
    """``(linear x, y (2,), angular.z)`` of a ``Twist``, or :class:`MessageError` for non-finite numbers."""
    values = [msg.linear.x, msg.linear.y, msg.angular.z]
    if not all(math.isfinite(v) for v in values):
        raise MessageError(f"twist: expected finite linear.x, linear.y, angular.z, received {values}")
    return np.array(values[:2], float), float(values[2])


def rotate(vector: np.ndarray, yaw: float) -> np.ndarray:
    """``vector (2,)`` rotated by ``yaw`` (base frame → map frame; ``-yaw`` back)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1]])


# -- goals, plans, cells ---------------------------------------------------------------------
def goal_message(goal: np.ndarray, seconds: float, frame: str):
    """A ``PoseStamped`` at ``goal (2,)``."""
    from geometry_msgs.msg import PoseStamped

    msg = PoseStamped()
    msg.header.stamp, msg.header.frame_id = stamp_of(seconds), frame
    msg.pose.position.x, msg.pose.position.y = float(goal[0]), float(goal[1])
    msg.pose.orientation.w = 1.0
    return msg


def read_goal(msg, frame: str) -> np.ndarray:
    """The ``(2,)`` position of a ``PoseStamped`` goal (frame and finiteness checked)."""
    if msg.header.frame_id != frame:
        raise MessageError(f"header.frame_id: expected {frame!r}, received {msg.header.frame_id!r}")
    goal = np.array([msg.pose.position.x, msg.pose.position.y], float)
    if not np.all(np.isfinite(goal)):
        raise MessageError(f"pose.position: expected finite x, y, received {goal.tolist()}")
    return goal


def path_message(points: np.ndarray, seconds: float, frame: str):
    """A ``nav_msgs/Path`` through ``points (m, 2)``."""
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path

    msg = Path()
    msg.header.stamp, msg.header.frame_id = stamp_of(seconds), frame
    for x, y in np.asarray(points, float):
        pose = PoseStamped()
        pose.header = msg.header
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg


def polygon_message(vertices: np.ndarray, seconds: float, frame: str):
    """A ``PolygonStamped`` with the vertices ``(V, 2)`` (empty for an empty cell)."""
    from geometry_msgs.msg import Point32, PolygonStamped

    msg = PolygonStamped()
    msg.header.stamp, msg.header.frame_id = stamp_of(seconds), frame
    msg.polygon.points = [Point32(x=float(x), y=float(y), z=0.0) for x, y in np.asarray(vertices, float).reshape(-1, 2)]
    return msg


def cell_markers(polygons: dict[int, np.ndarray], seconds: float, frame: str, lifetime: float):
    """A ``MarkerArray``: one closed ``LINE_STRIP`` per robot (id = robot index, namespace
    ``robofleet_cells``), shown for ``lifetime`` seconds unless replaced."""
    from builtin_interfaces.msg import Duration
    from geometry_msgs.msg import Point
    from visualization_msgs.msg import Marker, MarkerArray

    out = MarkerArray()
    for robot, vertices in sorted(polygons.items()):
        marker = Marker()
        marker.header.stamp, marker.header.frame_id = stamp_of(seconds), frame
        marker.ns, marker.id, marker.type, marker.action = "robofleet_cells", int(robot), Marker.LINE_STRIP, Marker.ADD
        marker.scale.x = 0.02
        marker.color.r, marker.color.g, marker.color.b, marker.color.a = 0.1, 0.4, 0.9, 0.9
        marker.pose.orientation.w = 1.0
        sec = math.floor(lifetime)
        marker.lifetime = Duration(sec=int(sec), nanosec=int((lifetime - sec) * 1e9))
        closed = np.concatenate([vertices, vertices[:1]]) if len(vertices) else vertices
        marker.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in closed]
        out.markers.append(marker)
    return out


def int_message(value: int):
    """A ``std_msgs/Int32``."""
    from std_msgs.msg import Int32

    return Int32(data=int(value))


def read_step(msg, length: int) -> int:
    """A plan step ``0..length`` from an ``Int32``, or :class:`MessageError`."""
    if not 0 <= msg.data <= length:
        raise MessageError(f"data: expected a plan step in 0..{length}, received {short_repr(msg.data)}")
    return int(msg.data)


def string_message(text: str):
    """A ``std_msgs/String``."""
    from std_msgs.msg import String

    return String(data=text)
