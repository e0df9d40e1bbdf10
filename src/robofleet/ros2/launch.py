"""``robofleet ros2 launch FILE.yaml``: start a described set of nodes as processes and
stop them together (there is no ROS launch package on PyPI).

The file::

    nodes:
      - node: sim                      # sim, filter or supervisor
        scenario: avoidance/circle_swap  # a shipped name, or a file (relative to this file)
        args: [--nominal, go-to-goal]  # the command's options, as on the command line
        required: true                 # when it exits, everything stops (default false)
      - node: filter
        scenario: avoidance/circle_swap
    env: {ROS_DOMAIN_ID: "7"}          # optional, added to every node's environment

Each node runs as ``python -m robofleet ros2 NODE SCENARIO ARGS`` in its own process
group, its output passed through. Ctrl-C (SIGINT) or SIGTERM to the launcher sends
SIGINT once to every node (the nodes stop cleanly: the simulator writes its run), waits
up to ``grace`` seconds, then terminates what is left. The launcher also stops every node
when a ``required`` node exits or when a node fails (non-zero status). Its exit status is
0 when every node stopped cleanly, else the first failing node's.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Literal

from pydantic import Field

from ..core.config import SpecModel, read_mapping, validate_model
from ..core.errors import ConfigError

GRACE_SECONDS = 10.0
NODE_KINDS = ("sim", "filter", "supervisor")


class LaunchNode(SpecModel):
    """One node of a launch file."""

    node: Literal["sim", "filter", "supervisor"]
    scenario: str = Field(min_length=1, description="scenario name or file (a filter also takes a ros__parameters file)")
    args: list[str] = Field(default_factory=list, description="further options, as on the command line")
    required: bool = False


class LaunchFile(SpecModel):
    """A launch file: the nodes, and environment variables for all of them."""

    nodes: list[LaunchNode] = Field(min_length=1)
    env: dict[str, str] = Field(default_factory=dict)


def read_launch_file(path: str | Path) -> LaunchFile:
    """The validated launch file (scenario files resolved relative to it)."""
    data, source = read_mapping(path)
    launch = validate_model(LaunchFile, data, source)
    base = Path(path).parent
    nodes = [node.model_copy(update={"scenario": str(base / node.scenario)}) if (base / node.scenario).is_file() else node
             for node in launch.nodes]
    return launch.model_copy(update={"nodes": nodes})


def command_of(node: LaunchNode) -> list[str]:
    return [sys.executable, "-m", "robofleet", "ros2", node.node, node.scenario, *node.args]


class Launcher:
    """The running processes of a launch file."""

    def __init__(self, launch: LaunchFile, grace: float = GRACE_SECONDS):
        self.launch, self.grace = launch, grace
        self.processes: list[tuple[LaunchNode, subprocess.Popen]] = []
        self.stopping = False
        self.status = 0

    def start(self) -> None:
        env = {**os.environ, **self.launch.env}
        for node in self.launch.nodes:
            process = subprocess.Popen(command_of(node), env=env, start_new_session=True)
            self.processes.append((node, process))
            print(f"[launch] started {node.node} {node.scenario} (pid {process.pid})", file=sys.stderr, flush=True)

    def request_stop(self, signum: int = signal.SIGINT, frame: object = None) -> None:
        self.stopping = True

    def watch(self) -> None:
        """Wait until a stop is requested, a required node exits, a node fails, or all exit."""
        while not self.stopping:
            running = 0
            for node, process in self.processes:
                code = process.poll()
                if code is None:
                    running += 1
                elif code != 0 or node.required:
                    if code != 0 and self.status == 0:
                        self.status = code
                    print(f"[launch] {node.node} exited with status {code}; stopping the others", file=sys.stderr, flush=True)
                    return
            if running == 0:
                return
            time.sleep(0.1)

    def stop(self) -> int:
        """SIGINT to every running node, wait ``grace`` seconds, then SIGTERM / SIGKILL."""
        for _, process in self.processes:
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + self.grace
        for node, process in self.processes:
            try:
                code = process.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                process.terminate()
                try:
                    code = process.wait(timeout=2.0)
                except subprocess.TimeoutExpired:
                    process.kill()
                    code = process.wait()
                print(f"[launch] {node.node} did not stop within {self.grace:g} s; terminated", file=sys.stderr, flush=True)
            if code not in (0, -signal.SIGINT) and self.status == 0:
                self.status = code if code > 0 else 128 - code
        return self.status


def launch(path: str | Path, grace: float = GRACE_SECONDS) -> int:
    """Run a launch file until Ctrl-C (or its nodes end); returns the exit status."""
    if not grace > 0:
        raise ConfigError(f"--grace: expected seconds > 0, received {grace!r}")
    launcher = Launcher(read_launch_file(path), grace)
    previous = {s: signal.signal(s, launcher.request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        launcher.start()
        launcher.watch()
    finally:
        status = launcher.stop()
        for s, handler in previous.items():
            signal.signal(s, handler)
    print(f"[launch] stopped {len(launcher.processes)} nodes (status {status})", file=sys.stderr, flush=True)
    return status
