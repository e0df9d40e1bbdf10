"""Closed loops over real topics, each node its own process: the simulator and the safety
filter bring the 8-robot circle swap home without contact; the simulator's plan followers
and the supervisor finish without contact although messages are lost and late."""

from __future__ import annotations

import pytest
from ros_harness import robofleet, stop

from robofleet.core.trace import Trace


def run_to_end(sim_args: list[str], partner_args: list[str], timeout: float = 240.0) -> tuple[int, str]:
    """Start the partner node, run the simulator until it ends, stop the partner (Ctrl-C)."""
    partner = robofleet("ros2", *partner_args)
    try:
        sim = robofleet("ros2", "sim", *sim_args)
        _, sim_err = sim.communicate(timeout=timeout)
    finally:
        code, _, err = stop(partner)
    assert sim.returncode == 0, sim_err[-2000:]
    assert code == 0 and "Traceback" not in err, err[-2000:]
    return sim.returncode, sim_err


def test_sim_and_filter_bring_the_circle_swap_home_without_contact(tmp_path):
    out = tmp_path / "run"
    zero_noise = ["--set", "robots.sigma=0"]
    run_to_end(["avoidance/circle_swap", *zero_noise, "--nominal", "go-to-goal", "--speed", "10", "--lockstep", "--wait-for-cmd-vel",
                "--out", out], ["filter", "avoidance/circle_swap", *zero_noise, "--use-sim-time"])
    trace = Trace.load(out)
    results = trace.results
    assert results["arrived"] == 1.0, results
    assert results["collisions"] == 0 and results["collision_steps"] == 0, results
    assert results["min_pair_distance"] >= 2 * trace.metadata["radius"] - 1e-9, results


@pytest.mark.slow
def test_with_the_scenarios_noise_the_contact_rate_stays_within_delta(tmp_path):
    out = tmp_path / "run"
    run_to_end(["avoidance/circle_swap", "--nominal", "go-to-goal", "--speed", "10", "--lockstep", "--wait-for-cmd-vel", "--seed", "3",
                "--out", out], ["filter", "avoidance/circle_swap", "--use-sim-time"])
    results = Trace.load(out).results
    assert results["arrived"] == 1.0, results
    assert results["pair_step_rate"] <= 0.1 and results["close_pair_step_rate"] <= 0.1, results


def test_supervisor_closed_loop_with_lost_and_late_messages(tmp_path):
    out = tmp_path / "run"
    scenario = "coordination/fig2_three_robots"
    run_to_end([scenario, "--speed", "10", "--drop", "0.3", "--delay", "0.5", "--seed", "1", "--wait-for-cmd-vel", "--out", out],
               ["supervisor", scenario, "--use-sim-time"])
    trace = Trace.load(out)
    results, md = trace.results, trace.metadata
    assert results["finished"] and results["collision_events"] == 0, results
    assert results["min_pair_distance"] >= 2 * md["radius"] - 1e-9, results
    assert md["messages_dropped"] > 0 and md["messages_delayed"] > 0, md
