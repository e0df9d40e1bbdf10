"""ROS 2 nodes over robofleet's embedding APIs (the ``ros2`` extra: ``pip install 'robofleet[ros2]'``).

The interface (names are the contract; see docs/ros2.md)
    Robots live in namespaces ``/robot0``, ``/robot1``, … (the prefix is configurable).
    Poses and velocities are in the ``map`` frame unless a parameter says ``base``.

    * ``robofleet ros2 sim SCENARIO`` (:mod:`.sim`): a simulated fleet. Avoidance
      scenarios: each robot publishes ``<ns>/pose`` (``PoseWithCovarianceStamped``: the
      true position plus the scenario's estimation noise, its covariance filled in) every
      ``dt`` and integrates the last ``<ns>/cmd_vel`` (``Twist``) it received;
      ``--nominal go-to-goal`` also publishes a straight-to-goal ``<ns>/cmd_vel_nav``; goals
      on ``<ns>/goal`` (``PoseStamped``). Coordination scenarios: each robot follows its
      plan step by step up to the last ``<ns>/until`` it received and publishes
      ``<ns>/progress`` (``Int32``) and ``<ns>/pose``.
    * ``robofleet ros2 filter SCENARIO|PARAMS.yaml`` (:mod:`.filter`): the B-UAVC safety
      filter in front of each robot's base: ``<ns>/cmd_vel_nav`` in, ``<ns>/cmd_vel`` out,
      every ``<ns>/pose`` read; ``<ns>/cell``, ``<ns>/safety_state`` and the
      ``/robofleet/cells`` markers out.
    * ``robofleet ros2 supervisor SCENARIO`` (:mod:`.supervisor`): the online RMTRACK
      supervisor: ``<ns>/progress`` or ``<ns>/pose`` in, ``<ns>/until`` and ``<ns>/plan`` out.
    * ``robofleet ros2 launch FILE.yaml`` (:mod:`.launch`): a set of these nodes as
      processes, stopped together on Ctrl-C.
    * ``robofleet export RUN --mcap FILE.mcap`` (:mod:`.mcap_export`): a recorded run as
      ROS 2 messages in an MCAP file.

Nothing here re-implements an algorithm: the filter calls
:class:`~robofleet.avoidance.safety_filter.RobotSafetyFilter`, the supervisor
:class:`~robofleet.coordination.supervisor.Supervisor`.
"""

from __future__ import annotations

from ..core import extras


def require_ros(what: str) -> None:
    """A one-line :class:`~robofleet.core.errors.ConfigError` naming the ``ros2`` extra
    when rclpy, the message packages or mcap are missing."""
    extras.require("ros2", what)
