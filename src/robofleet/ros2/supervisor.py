"""The online RMTRACK supervisor as a ROS 2 node (``robofleet ros2 supervisor SCENARIO``).

It holds one :class:`~robofleet.coordination.supervisor.Supervisor` over the plan of a
coordination scenario (the instance of ``seed``: the one ``robofleet ros2 sim`` and
:func:`robofleet.simulate` execute) and

* feeds it every ``<ns>/progress`` (``std_msgs/Int32``: the plan step the robot has
  reached) as ``report(i, progress=k)``, or, with ``reports="pose"``, every ``<ns>/pose``
  as ``report(i, position=(x, y))``;
* answers the robot right after each report, and every robot every ``dt``: it publishes
  ``<ns>/until`` (``std_msgs/Int32``, the last plan step the robot may reach; a robot
  whose progress is not below it holds) and ``<ns>/plan`` (``nav_msgs/Path``, the
  permitted segment: the planned positions from the known progress to ``until``).

Lost and late messages only make robots wait: a lost or late report leaves the
supervisor with a smaller known progress, which never makes an answer less safe (it only
waits more), and an older report arriving late changes nothing; an answer counts as
given when it is computed (the supervisor assumes the robot may have advanced to
``until``), so a lost or late ``until`` only holds the robot longer (the guarantees of
:mod:`robofleet.coordination.supervisor`). The robots must never pass the ``until`` they
last received.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..coordination.supervisor import Supervisor
from ..core.errors import ConfigError, RobofleetError
from .messages import MessageError, int_message, path_message, read_pose, read_step
from .runtime import DEFAULT_PREFIX, MAP_FRAME, BadInputLog, latched_qos, robot_of_topic, robot_topic, stream_qos, wall_clock

REPORTS = ("progress", "pose")
"""What the robots report: their plan step on ``<ns>/progress``, or their pose on ``<ns>/pose``."""


def supervisor_of(spec: Any, seed: int) -> Supervisor:
    """The supervisor of a coordination scenario's run ``seed``."""
    if getattr(spec, "family", None) != "coordination":
        raise ConfigError(f"SCENARIO: expected a coordination scenario, received a {getattr(spec, 'family', type(spec).__name__)} scenario")
    return Supervisor.from_scenario(spec, seed)


def make_supervisor_node(supervisor: Supervisor, prefix: str = DEFAULT_PREFIX, use_sim_time: bool = False, reports: str = "progress"):
    """The node around ``supervisor`` (robots ``/<prefix>0`` … ``/<prefix>{n-1}``)."""
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from nav_msgs.msg import Path
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from std_msgs.msg import Int32

    if reports not in REPORTS:
        raise ConfigError(f"--reports: expected one of {list(REPORTS)}, received {reports!r}")
    n, dt = supervisor.traj.n_robots, float(supervisor.traj.dt)
    lengths = np.asarray(supervisor.traj.lengths)
    qos = stream_qos()

    class SupervisorNode(Node):
        def __init__(self) -> None:
            super().__init__("robofleet_supervisor", parameter_overrides=[Parameter("use_sim_time", value=use_sim_time)])
            self.sup = supervisor
            self.bad = BadInputLog(self.get_logger())
            self.until = [self.create_publisher(Int32, robot_topic(prefix, i, "until"), qos) for i in range(n)]
            self.plans = [self.create_publisher(Path, robot_topic(prefix, i, "plan"), latched_qos()) for i in range(n)]
            for i in range(n):
                if reports == "progress":
                    self.create_subscription(Int32, robot_topic(prefix, i, "progress"), lambda m, i=i: self.on_progress(i, m), qos)
                else:
                    self.create_subscription(PoseWithCovarianceStamped, robot_topic(prefix, i, "pose"), lambda m, i=i: self.on_pose(i, m), qos)
            self.create_timer(dt, self.answer_all)
            self.create_timer(2.0, self.report_unknown_robots, clock=wall_clock())
            self.unknown_reported: set[str] = set()
            self.answered = 0
            self.get_logger().info(f"supervising {n} robots ({supervisor.executor.variant.method.value}), "
                                   f"{prefix}K/progress -> {prefix}K/until")

        def on_progress(self, i: int, msg) -> None:
            topic = robot_topic(prefix, i, "progress")
            try:
                self.sup.report(i, progress=read_step(msg, int(lengths[i])))
            except (MessageError, RobofleetError) as exc:
                self.bad(topic, str(exc))
                return
            self.answer(i)

        def on_pose(self, i: int, msg) -> None:
            topic = robot_topic(prefix, i, "pose")
            try:
                position = read_pose(msg, MAP_FRAME)[0]
                self.sup.report(i, position=position)
            except (MessageError, RobofleetError) as exc:
                self.bad(topic, str(exc))
                return
            self.answer(i)

        def answer(self, i: int) -> None:
            reply = self.sup.answer(i)
            self.until[i].publish(int_message(reply.until))
            segment = self.sup.traj.positions[i, reply.progress: reply.until + 1]
            self.plans[i].publish(path_message(segment, self.get_clock().now().nanoseconds * 1e-9, MAP_FRAME))
            self.answered += 1

        def answer_all(self) -> None:
            for i in range(n):
                self.answer(i)

        def report_unknown_robots(self) -> None:
            for topic, _ in self.get_topic_names_and_types():
                k = robot_of_topic(prefix, topic)
                if k is not None and k >= n and topic not in self.unknown_reported:
                    self.unknown_reported.add(topic)
                    self.get_logger().warning(f"{topic}: robot {k} is not in the plan's {n} robots; its messages are ignored")

        def finish(self) -> None:
            stats = self.sup.stats
            self.get_logger().info(f"answered {self.answered} times; flips {stats.get('flips', 0)}")

    return SupervisorNode()
