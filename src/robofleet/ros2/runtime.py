"""What every node shares: topic names, quality of service, one-line logging of bad
input, and the spin loop with a clean stop on Ctrl-C (SIGINT) or SIGTERM.

Only :func:`run_node` and the QoS helpers import rclpy (inside the functions), so this
module loads without the ``ros2`` extra.
"""

from __future__ import annotations

import re
import signal
import threading
import time
from collections.abc import Callable
from typing import Any

from ..core.errors import ConfigError, short_repr

DEFAULT_PREFIX = "robot"
"""Robots live in ``/robot0``, ``/robot1``, …"""
MAP_FRAME = "map"
"""The frame of poses, goals, cells and plans (and of velocities unless ``base`` is asked for)."""
CELLS_TOPIC = "/robofleet/cells"
"""Every robot's cell as a ``visualization_msgs/MarkerArray`` (for RViz)."""
VELOCITY_FRAMES = ("map", "base")
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def checked_prefix(prefix: object, name: str = "--prefix") -> str:
    """``prefix`` if it is a valid ROS name token (a letter, then letters, digits, ``_``)."""
    if not isinstance(prefix, str) or not _NAME.match(prefix):
        raise ConfigError(f"{name}: expected a ROS name (a letter, then letters, digits or _), received {short_repr(prefix)}")
    return prefix


def checked_frame(frame: object, name: str = "--frame") -> str:
    """``map`` or ``base``."""
    if frame not in VELOCITY_FRAMES:
        raise ConfigError(f"{name}: expected one of {list(VELOCITY_FRAMES)}, received {short_repr(frame)}")
    return str(frame)


def namespace(prefix: str, robot: int) -> str:
    """``/robot3``."""
    return f"/{prefix}{robot}"


def robot_topic(prefix: str, robot: int, name: str) -> str:
    """``/robot3/cmd_vel``."""
    return f"{namespace(prefix, robot)}/{name}"


def robot_of_topic(prefix: str, topic: str) -> int | None:
    """The robot index of ``/robot3/…`` (``None`` for another topic)."""
    match = re.match(rf"^/{re.escape(prefix)}(\d+)/", topic)
    return int(match.group(1)) if match else None


def latched_qos() -> Any:
    """Reliable, transient local, depth 1: a late subscriber still gets the last message
    (goals, plans)."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def stream_qos(depth: int = 10) -> Any:
    """Reliable, volatile: poses, commands, progress."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)


def wall_clock() -> Any:
    """A steady clock for timers that must run also while simulated time stands still."""
    from rclpy.clock import Clock, ClockType

    return Clock(clock_type=ClockType.STEADY_TIME)


class BadInputLog:
    """One log line per bad message, at most one per ``(topic, reason)`` every ``period``
    seconds (a stream of malformed messages does not flood the log); the node goes on."""

    def __init__(self, logger: Any, period: float = 2.0):
        self.logger, self.period = logger, period
        self.last: dict[tuple[str, str], float] = {}
        self.count = 0

    def __call__(self, topic: str, reason: str) -> None:
        self.count += 1
        now = time.monotonic()
        key = (topic, reason.split(",")[0])
        if now - self.last.get(key, -1e18) >= self.period:
            self.last[key] = now
            self.logger.warning(f"{topic}: {reason}; message ignored")


def run_node(make_node: Callable[[], Any], done: Callable[[Any], bool] | None = None) -> int:
    """Start rclpy, build the node, spin it until ``done(node)`` or Ctrl-C / SIGTERM, then
    destroy it and shut rclpy down. Returns the exit status: 0 for a normal stop.

    Ctrl-C and SIGTERM only ask the loop to stop (checked every 0.1 s); they raise nothing,
    so a signal that lands inside a callback or a first kernel compile cannot print an
    ignored exception there. (rclpy's own handlers, which raise ``KeyboardInterrupt``
    wherever the main thread is, stay off while a handler of ours is installed.)"""
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    stop = threading.Event()
    ours = threading.current_thread() is threading.main_thread()
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)} if ours else {}
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO if ours else None)
    node = None
    try:
        node = make_node()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while rclpy.ok() and not stop.is_set() and not (done is not None and done(node)):
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # a shutdown from outside invalidates the handles; a take in flight then fails on
        # its handle. That is the stop, not an error of the node.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            finish = getattr(node, "finish", None)
            if callable(finish):
                finish()
            node.destroy_node()
        rclpy.try_shutdown()
        for number, handler in previous.items():
            signal.signal(number, handler)
    return 0
