"""Latency and CPU of the ROS 2 safety-filter node (``robofleet ros2 filter``) at 8 and 100 robots.

One filter process serves the fleet. This script is every robot at once: it publishes
each robot's pose (stamped now, σ = 0.1 m) and, every ``dt`` = 0.1 s, a burst of
``cmd_vel_nav`` for all robots (as a fleet's planners would), and takes the time from
publishing robot i's ``cmd_vel_nav`` to receiving its ``cmd_vel`` (same machine, same
clock). A burst that takes longer than ``dt`` delays the next one (closed loop: the
achieved rate is reported). CPU is the filter process's user + system time over the
measurement window divided by the window's wall time (100 % = one core).

Run: ``python benchmarks/ros2_latency.py [--seconds 10] [--robots 8 100]``
(needs the ros2 extra; uses ROS_DOMAIN_ID 77 and localhost-only discovery unless set).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

DT = 0.1


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def grid(n: int, spacing: float = 1.0) -> np.ndarray:
    side = int(np.ceil(np.sqrt(n)))
    xy = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n] * spacing
    return xy - xy.mean(axis=0)


def measure(n: int, seconds: float) -> dict:
    import rclpy
    from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
    from rclpy.executors import SingleThreadedExecutor

    from robofleet.ros2.messages import pose_message, twist_message

    half = max(10.0, 0.75 * np.sqrt(n) + 2)
    args = ["--set", f"robots.n={n}", "--set", f"robots.layout.radius={half - 2}",
            "--set", f"workspace.bounds=[{-half}, {-half}, {half}, {half}]"]
    node_process = subprocess.Popen([sys.executable, "-m", "robofleet", "ros2", "filter", "avoidance/circle_swap", *args],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    rclpy.init()
    node = rclpy.create_node("ros2_latency")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    poses = [node.create_publisher(PoseWithCovarianceStamped, f"/robot{i}/pose", 10) for i in range(n)]
    commands = [node.create_publisher(Twist, f"/robot{i}/cmd_vel_nav", 10) for i in range(n)]
    sent, latencies = np.zeros(n), []
    received: set[int] = set()

    def on_answer(i: int, _msg) -> None:
        latencies.append(time.perf_counter() - sent[i])
        received.add(i)

    for i in range(n):
        node.create_subscription(Twist, f"/robot{i}/cmd_vel", lambda m, i=i: on_answer(i, m), 10)
    while not all(p.get_subscription_count() > 0 for p in poses + commands) or \
            any(node.count_publishers(f"/robot{i}/cmd_vel") == 0 for i in range(n)):
        executor.spin_once(timeout_sec=0.1)
    positions = grid(n)
    cov = 0.01 * np.eye(2)
    desired = np.tile([0.3, 0.1], (n, 1))

    def burst() -> None:
        now = time.time()
        for i in range(n):
            poses[i].publish(pose_message(positions[i], cov, now, "map"))
        received.clear()
        for i in range(n):
            sent[i] = time.perf_counter()
            commands[i].publish(twist_message(desired[i]))
        deadline = time.perf_counter() + 2.0
        while len(received) < n and time.perf_counter() < deadline:
            executor.spin_once(timeout_sec=0.01)

    for _ in range(10):  # warm-up: every robot's pose reaches the node
        burst()
    latencies.clear()
    cpu0, t0, bursts = cpu_seconds(node_process.pid), time.perf_counter(), 0
    while time.perf_counter() - t0 < seconds:
        start = time.perf_counter()
        burst()
        bursts += 1
        time.sleep(max(0.0, DT - (time.perf_counter() - start)))
    wall = time.perf_counter() - t0
    cpu = (cpu_seconds(node_process.pid) - cpu0) / wall
    node.destroy_node()
    rclpy.shutdown()
    node_process.send_signal(signal.SIGINT)
    node_process.wait(timeout=30)
    lat = np.array(latencies) * 1e3
    return {"robots": n, "bursts_per_s": bursts / wall, "answers": len(lat), "answered_share": len(lat) / (bursts * n),
            "p50_ms": float(np.percentile(lat, 50)), "p99_ms": float(np.percentile(lat, 99)), "cpu_percent": 100 * cpu}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--robots", type=int, nargs="+", default=[8, 100])
    options = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", "77")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    print("| robots | bursts/s (target 10) | answered | latency p50 [ms] | latency p99 [ms] | filter CPU [% of a core] |")
    print("|---|---|---|---|---|---|")
    for n in options.robots:
        r = measure(n, options.seconds)
        print(f"| {r['robots']} | {r['bursts_per_s']:.1f} | {100 * r['answered_share']:.0f} % | {r['p50_ms']:.1f} | {r['p99_ms']:.1f} | "
              f"{r['cpu_percent']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
