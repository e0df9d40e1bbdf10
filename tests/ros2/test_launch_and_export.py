"""The launcher starts its nodes and stops them cleanly on Ctrl-C; a run exported to MCAP
reads back with the mcap reader; without the extra the commands say what to install."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import yaml
from geometry_msgs.msg import Twist
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from ros_harness import robofleet, stop

from robofleet import load_scenario, simulate
from robofleet.cli.main import main
from robofleet.core.trace import Trace


def test_launch_starts_the_nodes_and_ctrl_c_stops_them_cleanly(tmp_path, harness):
    out = tmp_path / "run"
    launch_file = tmp_path / "fleet.yaml"
    launch_file.write_text(yaml.safe_dump({"nodes": [
        {"node": "sim", "scenario": "avoidance/circle_swap", "args": ["--nominal", "go-to-goal", "--speed", "5", "--out", str(out)]},
        {"node": "filter", "scenario": "avoidance/circle_swap", "args": ["--use-sim-time"]}]}))
    launcher = robofleet("ros2", "launch", launch_file)
    got = []
    harness.node.create_subscription(Twist, "/robot0/cmd_vel", got.append, 10)
    try:
        harness.spin_until(lambda: len(got) >= 5, what="filtered commands from the launched nodes")
    finally:
        code, _, err = stop(launcher, timeout=60)
    assert code == 0, err[-3000:]
    assert "Traceback" not in err and "terminated" not in err, err[-3000:]
    assert "stopped 2 nodes (status 0)" in err
    trace = Trace.load(out)  # the simulator wrote its run on the way out
    assert trace.metadata["n_steps"] > 0


def test_a_run_exported_to_mcap_reads_back_as_ros2_messages(tmp_path):
    spec = load_scenario("avoidance/circle_swap", {"max_steps": 12})
    run = tmp_path / "run"
    simulate(spec, seed=4).save(run)
    mcap = tmp_path / "run.mcap"
    result = subprocess.run([sys.executable, "-m", "robofleet", "export", str(run), "--mcap", str(mcap)], capture_output=True, text=True)
    assert result.returncode == 0 and "messages" in result.stdout, result.stderr
    trace = Trace.load(run)
    poses, cells, schemas = {}, 0, set()
    with open(mcap, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            schemas.add(schema.name)
            if channel.topic == "/robot3/pose":
                poses[message.log_time] = decoded
            if channel.topic == "/robot3/cell":
                cells += 1
    assert {"geometry_msgs/msg/PoseWithCovarianceStamped", "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PolygonStamped",
            "visualization_msgs/msg/MarkerArray"} <= schemas
    estimates = trace.arrays["estimates"][:, 3]
    assert len(poses) == len(estimates) and cells == len(trace.arrays["cell_A"])
    for k, (t, pose) in enumerate(sorted(poses.items())):
        assert t == round(k * spec.dt * 1e9) and pose.header.frame_id == "map"
        np.testing.assert_allclose([pose.pose.pose.position.x, pose.pose.pose.position.y], estimates[k])
        cov = np.asarray(pose.pose.covariance).reshape(6, 6)[:2, :2]
        np.testing.assert_allclose(cov, np.asarray(trace.metadata["robot_cov"]))


def run_cli(args, capsys) -> tuple[int, list[str]]:
    """``robofleet ARGS`` in this process: the exit status and the lines on stderr."""
    capsys.readouterr()
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err.strip().splitlines()


def test_without_the_ros2_extra_each_command_is_one_line_naming_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "rclpy", None)  # as if the extra were not installed
    for args in (["ros2", "sim", "avoidance/circle_swap"], ["ros2", "filter", "avoidance/circle_swap"],
                 ["ros2", "supervisor", "coordination/fig2_three_robots"], ["ros2", "launch", "x.yaml"],
                 ["export", tmp_path, "--mcap", tmp_path / "x.mcap"]):
        code, lines = run_cli(args, capsys)
        assert code == 2 and len(lines) == 1, (args, lines)
        assert lines[0].startswith("error: ") and "pip install 'robofleet[ros2]'" in lines[0] and "rclpy" in lines[0], lines


def test_bad_parameters_are_one_line_with_exit_status_2(tmp_path, capsys):
    params = tmp_path / "filter.yaml"
    params.write_text(yaml.safe_dump({"robofleet_filter": {"ros__parameters": {"robots": 4, "radius": -0.2, "v_max": 0.4, "dt": 0.1}}}))
    cases = [(["ros2", "filter", params], f"{params}: radius: expected"),
             (["ros2", "filter", "avoidance/circle_swap", "--robot", "8"], "--robot: expected a robot index in 0..7, received 8"),
             (["ros2", "filter", "avoidance/circle_swap", "--frame", "odom"], "--frame: expected one of ['map', 'base'], received 'odom'"),
             (["ros2", "filter", "coordination/fig2_three_robots"], "expected an avoidance scenario or a ros__parameters file"),
             (["ros2", "sim", "avoidance/circle_swap", "--nominal", "fast"], "--nominal: expected one of ['none', 'go-to-goal']"),
             (["ros2", "sim", "avoidance/circle_swap", "--set", "robots.sigma"], "--set: expected FIELD=VALUE"),
             (["ros2", "supervisor", "avoidance/circle_swap"], "expected a coordination scenario, received a avoidance scenario"),
             (["export", tmp_path, "--mcap", tmp_path / "x.txt"], "--mcap: expected a FILE.mcap")]
    for args, text in cases:
        code, lines = run_cli(args, capsys)
        assert code == 2 and len(lines) == 1 and text in lines[0], (args, lines)
