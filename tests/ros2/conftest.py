"""The ROS 2 tests run real rclpy nodes (the ros2 extra is part of `make test`'s install:
these tests never skip). Each pytest worker gets its own ROS_DOMAIN_ID, derived from the
xdist worker and the process id, and discovery stays on this machine."""

from __future__ import annotations

import os

import pytest
import rclpy  # noqa: F401  (a missing extra fails here, loudly: the ROS tests must not skip)
from ros_harness import Harness, domain_id


@pytest.fixture(scope="session", autouse=True)
def isolated_ros_domain():
    saved = {k: os.environ.get(k) for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "MPLBACKEND",
                                             "RCUTILS_LOGGING_BUFFERED_STREAM")}
    os.environ.update(ROS_DOMAIN_ID=str(domain_id()), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", MPLBACKEND="Agg",
                      RCUTILS_LOGGING_BUFFERED_STREAM="0")
    os.environ.pop("ROS_LOCALHOST_ONLY", None)  # superseded by the discovery range (and warned about when both are set)
    yield
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture
def harness():
    h = Harness()
    yield h
    h.close()
