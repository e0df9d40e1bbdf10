"""End to end on a real family: sweeps and the CLI on the shipped circle-swap scenario."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pandas as pd
import yaml

from robofleet import load_scenario, simulate
from robofleet.experiments import deterministic_columns, run_sweep, summarize_sweep

ROOT = Path(__file__).resolve().parents[2]
CIRCLE = ROOT / "scenarios" / "avoidance" / "circle_swap.yaml"


def small_sweep(tmp_path) -> Path:
    path = tmp_path / "circle_sweep.yaml"
    path.write_text(yaml.safe_dump({
        "scenario": str(CIRCLE),
        "grid": {"method": ["buavc", "bvc"], "robots.sigma": [0.0, 0.05], "robots.n": [4], "max_steps": [60]},
        "seeds": 2,
        "root_seed": 11,
    }, sort_keys=False))
    return path


def test_avoidance_sweep_is_replayable_and_identical_on_every_executor(tmp_path):
    path = small_sweep(tmp_path)
    serial = run_sweep(path, executor="serial", progress=False, out=tmp_path / "serial")
    process = run_sweep(path, executor="process", workers=2, progress=False, out=tmp_path / "process")
    dask = run_sweep(path, executor="dask", workers=2, progress=False, out=tmp_path / "dask")
    assert len(serial) == 8 and serial["error"].isna().all()
    columns = deterministic_columns(serial)
    pd.testing.assert_frame_equal(serial[columns], process[columns])
    pd.testing.assert_frame_equal(serial[columns], dask[columns])
    row = serial.iloc[5]
    spec = load_scenario(CIRCLE, overrides={k: (int(row[k]) if k in ("robots.n", "max_steps") else row[k]) for k in serial.attrs["grid"]})
    replay = simulate(spec, seed=int(row["seed"])).summary()
    assert replay["min_pair_distance"] == row["min_pair_distance"] and replay["n_steps"] == row["n_steps"]
    means = summarize_sweep(serial)
    assert means["runs"].tolist() == [2, 2, 2, 2] and means["method"].tolist() == ["buavc", "buavc", "bvc", "bvc"]


def test_grid_value_invalid_for_avoidance_is_reported_before_running(tmp_path, robofleet_bin):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"scenario": str(CIRCLE), "grid": {"delta": [0.1, 1.5]}, "seeds": 1, "out": str(tmp_path / "o")}))
    result = subprocess.run([str(robofleet_bin), "sweep", str(path)], capture_output=True, text=True)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.startswith(f"error: {path}: grid delta=1.5 → {CIRCLE}: delta: expected")
    assert not (tmp_path / "o").exists()


def test_cli_run_validate_and_sweep_on_circle_swap(tmp_path, robofleet_bin):
    ok = subprocess.run([str(robofleet_bin), "validate", str(CIRCLE)], capture_output=True, text=True)
    assert ok.returncode == 0 and ok.stdout.strip() == f"ok: {CIRCLE} (avoidance)"
    small = tmp_path / "small_circle.yaml"
    doc = yaml.safe_load(CIRCLE.read_text())
    doc["robots"]["n"], doc["max_steps"] = 4, 60
    small.write_text(yaml.safe_dump(doc))
    out = tmp_path / "run"
    run = subprocess.run([str(robofleet_bin), "run", str(small), "--seed", "1", "--out", str(out), "--quiet"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert {"success", "collisions", "min_pair_distance", "min_obstacle_distance", "makespan", "mean_travel_time", "median_step_seconds"} <= set(summary)
    sweep = subprocess.run([str(robofleet_bin), "sweep", str(small_sweep(tmp_path)), "--executor", "serial", "--out", str(tmp_path / "s")], capture_output=True, text=True)
    assert sweep.returncode == 0, sweep.stderr
    assert f"results: {tmp_path / 's'}/ (8 runs, 0 failed)" in sweep.stdout


def test_run_animate_writes_a_gif_through_the_family_viz(tmp_path):
    from PIL import Image

    from robofleet.cli.main import main

    small = tmp_path / "tiny.yaml"
    doc = yaml.safe_load(CIRCLE.read_text())
    doc["robots"]["n"], doc["max_steps"] = 3, 12
    small.write_text(yaml.safe_dump(doc))
    main(["run", str(small), "--out", str(tmp_path / "r"), "--animate", "--quiet"])
    with Image.open(tmp_path / "r" / "animation.gif") as gif:
        assert gif.n_frames == 13  # one frame per recorded step (initial state included)
