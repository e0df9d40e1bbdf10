"""Helpers of the ROS 2 tests: node processes and the test's own rclpy node."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import rclpy

DOMAIN_SPAN = 90  # domains 10..99: Fast DDS's ports stay valid below 101


def domain_id() -> int:
    """A ROS domain for this test process: the xdist worker number spreads workers apart,
    the pid separates concurrent pytest runs."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    index = int(re.sub(r"\D", "", worker) or 0)
    return 10 + (index * 17 + os.getpid()) % DOMAIN_SPAN


def robofleet(*args: str, **popen) -> subprocess.Popen:
    """``python -m robofleet ARGS`` as a child process (stdout and stderr captured as text)."""
    src = str(Path(__file__).resolve().parents[2] / "src")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [src, os.environ.get("PYTHONPATH")]))}
    return subprocess.Popen([sys.executable, "-m", "robofleet", *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, **popen)


def stop(process: subprocess.Popen, timeout: float = 30.0) -> tuple[int, str, str]:
    """Ctrl-C (SIGINT) to a node; its exit status and output."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
        raise AssertionError(f"the node did not stop on SIGINT within {timeout} s: {err[-2000:]}") from None
    return process.returncode, out, err


class LoggedNode:
    """A node process whose stderr lines are collected as they come (for log checks)."""

    def __init__(self, *args: str):
        self.process = robofleet(*args)
        self.lines: list[str] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.process.stderr:
            self.lines.append(line.rstrip("\n"))

    def stop(self, timeout: float = 30.0) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            code = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            raise AssertionError(f"the node did not stop on SIGINT within {timeout} s") from None
        self.reader.join(timeout=5)
        return code


class Harness:
    """The test's own rclpy node: publish, subscribe, and spin until a condition holds."""

    def __init__(self, name: str = "robofleet_test"):
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, condition, limit: float = 90.0, what: str = "a condition") -> None:
        """Spin until ``condition()``; the limit only ends a hung test (it asserts nothing about speed)."""
        deadline = time.monotonic() + limit
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f"gave up waiting for {what} after {limit} s")
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


