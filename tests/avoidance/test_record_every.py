"""``record_every``: a run that keeps every k-th step is the same run, its kept rows are
rows 0, k, 2k, … of the full trace, and its per-run results are judged on every step."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import robofleet
from robofleet.avoidance.metrics import run_results, ControllerCounts
from robofleet.cli.main import main
from robofleet.core.errors import ConfigError, ScenarioError
from robofleet.core.recorder import Recorder

CASES = {
    "contacts": ("avoidance/three_boxes", {"method": "bvc", "robots.sigma": 0.3, "max_steps": 150}),
    "orca": ("avoidance/circle_swap", {"method": "orca", "max_steps": 40}),
    "quadrotors": ("avoidance/quadrotors_3d", {"max_steps": 9}),
}


def run(name: str, overrides: dict, every: int, seed: int = 4):
    return robofleet.simulate(robofleet.load_scenario(name, {**overrides, "record_every": every}), seed=seed)


def comparable(results: dict) -> dict:
    """The results without the measured compute time."""
    return {k: v for k, v in results.items() if k != "median_step_seconds"}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("every", [3, 7])
def test_kept_rows_are_every_kth_row_of_the_full_trace_and_summaries_are_identical(case, every):
    name, overrides = CASES[case]
    full, kept = run(name, overrides, 1), run(name, overrides, every)
    assert kept.record_every == every and full.record_every == 1
    assert kept.metadata["n_steps"] == full.metadata["n_steps"]
    for array, values in full.arrays.items():
        if array in ("step_seconds", "arrival_steps"):
            assert len(kept.arrays[array]) == len(values), array  # one entry per step / robot
            continue
        expected = values[::every]
        if array in ("cell_A", "cell_b"):  # padded to the widest kept step with always-true rows 0·p ≤ 1
            width = kept.arrays[array].shape[2]
            padding = expected[:, :, width:]
            assert np.all(padding == (0.0 if array == "cell_A" else 1.0)), array
            expected = expected[:, :, :width]
        np.testing.assert_array_equal(kept.arrays[array], expected, err_msg=array)
    np.testing.assert_array_equal(kept.arrays["arrival_steps"], full.arrays["arrival_steps"])
    assert kept.events == full.events
    np.testing.assert_equal(comparable(kept.results), comparable(full.results))


def test_results_count_every_step_not_only_the_kept_ones():
    name, overrides = CASES["contacts"]
    kept = run(name, overrides, 7)
    assert kept.results["collision_steps"] > 0  # a run with contacts
    only_kept = run_results(kept.positions, np.asarray(kept.metadata["goals"]), radius=kept.metadata["radius"], dt=0.1,
                            goal_tolerance=0.1, workspace=kept.workspace, boxes=None, step_seconds=kept.arrays["step_seconds"],
                            arrivals=kept.arrays["arrival_steps"], counts=ControllerCounts())
    assert only_kept["collision_steps"] < kept.results["collision_steps"]


def test_recorder_keeps_every_kth_row_and_shows_every_state_to_its_watcher():
    seen = []
    rec = Recorder(max_steps=10, n_robots=1, record_every=3)
    rec.state("x", (1,), initial=[0.0], watch=lambda row, value: seen.append((row, float(value[0]))))
    rec.step("u", (1,))

    def step(k):
        rec.put(k, u=[float(k)], step_seconds=0.5)
        rec.put_state(k + 1, x=[float(k + 1)])
        return k == 7  # stop after 8 steps

    assert rec.run(step) == 8
    arrays = rec.arrays()
    assert arrays["x"][:, 0].tolist() == [0.0, 3.0, 6.0]  # states after 0, 3, 6 steps (≤ 8)
    assert arrays["u"][:, 0].tolist() == [0.0, 3.0, 6.0]  # steps 0, 3, 6 (< 8)
    assert arrays["step_seconds"].tolist() == [0.5] * 8  # compute times of every step
    assert seen == [(row, float(row)) for row in range(9)]


@pytest.mark.parametrize("bad", [0, -2, True, 1.5, "3", None])
def test_the_recorder_refuses_a_bad_record_every(bad):
    with pytest.raises(ConfigError, match=r"^record_every: expected an integer ≥ 1"):
        Recorder(max_steps=5, n_robots=1, record_every=bad)


@pytest.mark.parametrize("bad", [0, -1, True, 2.5, "often", [2]])
def test_a_bad_record_every_is_a_one_line_scenario_error(bad):
    with pytest.raises(ScenarioError, match="record_every") as info:
        robofleet.load_scenario("avoidance/circle_swap", {"record_every": bad})
    assert "\n" not in str(info.value)


def test_validate_refuses_a_bad_record_every_in_one_line(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"family": "avoidance", "max_steps": 20, "record_every": 0,
                                    "robots": {"n": 3, "layout": {"kind": "circle", "radius": 3.0}}}))
    with pytest.raises(SystemExit) as info:
        main(["validate", str(path)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and len(lines) == 1 and "record_every" in lines[0], lines


def test_the_memory_budget_counts_the_kept_rows_only():
    mapping = {"family": "avoidance", "max_steps": 100, "record_cells": False,
               "workspace": {"bounds": [-127400, -127400, 127400, 127400]},
               "robots": {"n": 1_000_000, "radius": 0.2, "layout": {"kind": "circle", "radius": 127324.0}}}
    with pytest.raises(ScenarioError, match="memory budget"):
        robofleet.load_scenario(mapping)  # 101 states of a million robots: beyond 4 GiB
    spec = robofleet.load_scenario({**mapping, "record_every": 10})
    size = spec.run_size()
    assert size.recorded_bytes == 11 * 1_000_000 * size.bytes_per_robot_step + 101 * 8
    assert "1 in 10 recorded" in str(size.describe())


def test_the_estimate_bounds_a_decimated_run():
    spec = robofleet.load_scenario("avoidance/ten_boxes", {"max_steps": 13, "record_every": 4})
    trace = robofleet.simulate(spec, seed=1)
    assert sum(a.nbytes for a in trace.arrays.values()) <= spec.run_size().nbytes
    assert len(trace.positions) == 4  # states after 0, 4, 8, 12 steps
