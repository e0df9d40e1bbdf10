"""The generic commands over the family table: run, validate, check, scenarios, sweep, reproduce."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

import robofleet
from robofleet import load_scenario, simulate
from robofleet.cli.main import main
from robofleet.core.trace import CORE_SUMMARY_KEYS, Trace, to_plain
from robofleet.testing import without_timings

TOY = {"family": "toy", "robots": {"n": 3, "radius": 0.2}, "noise": {"sigma": 0.1}, "steps": 12}


def run_cli(robofleet_bin, *args, cwd=None):
    return subprocess.run([str(robofleet_bin), *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=120)


def assert_one_line_error(result, *words):
    assert result.returncode == 2, result
    assert "Traceback" not in result.stderr and "Traceback" not in result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    for word in words:
        assert word in lines[0]


@pytest.fixture
def toy_file(tmp_path):
    path = tmp_path / "toy.yaml"
    path.write_text(yaml.safe_dump(TOY))
    return path


def test_validate_bad_files_exit_2_with_one_line(tmp_path, robofleet_bin):
    bad = tmp_path / "bad.yaml"
    bad.write_text("family: nope\n")
    assert_one_line_error(run_cli(robofleet_bin, "validate", bad), str(bad), "family", "'nope'")
    assert_one_line_error(run_cli(robofleet_bin, "validate", tmp_path / "absent.yaml"), "absent.yaml", "readable YAML")
    broken = tmp_path / "broken.yaml"
    broken.write_text("robots: [1, 2\n")
    assert_one_line_error(run_cli(robofleet_bin, "run", broken), "broken.yaml", "valid YAML")


def test_sweep_errors_exit_2_with_one_line(tmp_path, robofleet_bin):
    sweep = tmp_path / "s.yaml"
    sweep.write_text("scenario: toy.yaml\ngrid: {robots.n: []}\nseeds: 2\n")
    assert_one_line_error(run_cli(robofleet_bin, "sweep", sweep), "s.yaml", "grid.robots.n", "non-empty list")
    sweep.write_text("scenario: toy.yaml\nseeds: 0\n")
    assert_one_line_error(run_cli(robofleet_bin, "sweep", sweep), "s.yaml", "seeds")
    assert_one_line_error(run_cli(robofleet_bin, "sweep", sweep, "--executor", "threads"), "executor", "'threads'", "'dask'")


def test_usage_errors_are_one_line_naming_option_and_received_value(tmp_path, robofleet_bin):
    assert_one_line_error(run_cli(robofleet_bin, "run", tmp_path / "x.yaml", "--seed", "x"), "--seed", "received 'x'", "run --help")
    assert_one_line_error(run_cli(robofleet_bin, "run", tmp_path / "x.yaml", "--seed=-3"), "--seed", "received '-3'")
    assert_one_line_error(run_cli(robofleet_bin, "run"), "scenario", "run --help")
    assert_one_line_error(run_cli(robofleet_bin, "no-such-command"), "no-such-command")
    assert_one_line_error(run_cli(robofleet_bin, "validate", tmp_path / "x.yaml", "--bogus"), "--bogus")


def test_python_dash_m_is_the_same_command_line():
    result = subprocess.run([sys.executable, "-m", "robofleet", "--version"], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip() == f"robofleet {robofleet.__version__}"


def test_run_writes_trace_and_strict_json_summary(tmp_path, toy_family, toy_file, capsys):
    out = tmp_path / "run"
    main(["run", str(toy_file), "--seed", "4", "--out", str(out)])
    printed = capsys.readouterr().out
    assert "final_spread" in printed and f"wrote {out}" in printed and "(seed 4)" in printed
    summary = json.loads((out / "summary.json").read_text(), parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    expected = simulate(load_scenario(toy_file), seed=4).summary()
    assert list(summary)[:7] == list(CORE_SUMMARY_KEYS)
    assert without_timings(summary) == without_timings(to_plain(expected, json_safe=True))
    trace = Trace.load(out)
    np.testing.assert_array_equal(trace.positions, simulate(load_scenario(toy_file), seed=4).positions)


def test_run_without_seed_prints_the_drawn_seed_and_replays(tmp_path, toy_family, toy_file, capsys):
    main(["run", str(toy_file), "--out", str(tmp_path / "a"), "--quiet"])
    seed = int(capsys.readouterr().out.strip().rsplit("seed ", 1)[1].rstrip(")"))
    assert Trace.load(tmp_path / "a").seed == seed
    main(["run", str(toy_file), "--out", str(tmp_path / "b"), "--quiet", "--seed", str(seed)])
    np.testing.assert_array_equal(Trace.load(tmp_path / "a").positions, Trace.load(tmp_path / "b").positions)


def test_run_default_out_and_quiet(tmp_path, toy_family, toy_file, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    main(["run", str(toy_file), "--seed", "2", "--quiet"])
    printed = capsys.readouterr().out
    assert printed.strip() == "wrote runs/toy-seed2/ {trace.npz, trace.json, summary.json} (seed 2)"
    assert (tmp_path / "runs" / "toy-seed2" / "summary.json").is_file()


def test_animate_without_a_viz_module_fails_cleanly_and_keeps_the_run(tmp_path, toy_family, toy_file, capsys):
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as info:
        main(["run", str(toy_file), "--out", str(out), "--animate", "--quiet"])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: family 'toy': viz: expected a figures module") and "\n" not in err
    assert sorted(p.name for p in out.iterdir()) == ["summary.json", "trace.json", "trace.npz"]


def test_check_prints_each_guarantee(toy_family, toy_file, capsys):
    main(["check", str(toy_file)])
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].endswith("toy random walk — nobody 2026")
    assert lines[1] == "noise-free convergence (toy model): no — sigma = 0.1"


def test_scenarios_lists_every_shipped_name_and_every_command_takes_one(capsys):
    main(["scenarios"])
    rows = capsys.readouterr().out.strip().splitlines()
    names = [row.split()[0] for row in rows]
    assert names == robofleet.scenarios.names() and "avoidance/circle_swap" in names
    assert {row.split()[1] for row in rows} == set(robofleet.scenarios.FAMILIES)
    main(["validate", "avoidance/circle_swap"])
    assert capsys.readouterr().out.strip().endswith("circle_swap.yaml (avoidance)")
    main(["scenarios", "--sweeps"])
    assert capsys.readouterr().out.strip()


def test_unknown_names_are_one_line_errors(robofleet_bin):
    assert_one_line_error(run_cli(robofleet_bin, "validate", "avoidance/no_such"), "shipped scenario name", "avoidance/no_such")
    assert_one_line_error(run_cli(robofleet_bin, "reproduce", "nothing"), "NAME", "'nothing'")
    assert_one_line_error(run_cli(robofleet_bin, "scenarios", "--family", "nope"), "--family", "'nope'")


def test_version_and_help_name_papers_by_author(robofleet_bin):
    assert run_cli(robofleet_bin, "--version").stdout.strip() == f"robofleet {robofleet.__version__}"
    text = run_cli(robofleet_bin, "--help").stdout + run_cli(robofleet_bin, "reproduce", "--help").stdout
    for family in robofleet.scenarios.FAMILIES.values():
        assert family.paper.split()[0] in text
    assert "paper 00" not in text


def test_validate_ok(toy_family, toy_file, capsys):
    main(["validate", str(toy_file)])
    assert capsys.readouterr().out.strip() == f"ok: {toy_file} (toy)"


def test_validate_reports_bad_field_in_process(tmp_path, toy_family, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({**TOY, "robots": {"n": 0}}))
    with pytest.raises(SystemExit) as info:
        main(["validate", str(bad)])
    assert info.value.code == 2
    assert capsys.readouterr().err.strip().startswith(f"error: {bad}: robots.n: expected")


def test_sweep_prints_store_and_means_and_resumes(tmp_path, toy_family, toy_file, capsys):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"scenario": "toy.yaml", "grid": {"robots.n": [2, 3]}, "seeds": 2}))
    out = tmp_path / "store"
    main(["sweep", str(sweep), "--executor", "serial", "--out", str(out)])
    printed = capsys.readouterr().out
    assert f"results: {out}/ (4 runs, 0 failed)" in printed
    assert "means per parameter combination" in printed and "robots.n" in printed
    files = {p.name: p.stat().st_mtime_ns for p in out.glob("*.parquet")}
    assert len(files) == 1  # the four runs are written together
    main(["sweep", str(sweep), "--executor", "serial", "--out", str(out)])
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.parquet")} == files


def test_out_over_an_earlier_run_needs_overwrite_which_clears_its_files(tmp_path, toy_family, toy_file, capsys):
    out = tmp_path / "run"
    main(["run", str(toy_file), "--seed", "1", "--out", str(out), "--quiet"])
    (out / "notes.txt").write_text("mine")
    with pytest.raises(SystemExit) as info:
        main(["run", str(toy_file), "--seed", "2", "--out", str(out), "--quiet"])
    assert info.value.code == 2
    assert capsys.readouterr().err.strip().startswith(f"error: --out: expected a new or empty directory (or --overwrite), received {out}")
    assert Trace.load(out).seed == 1
    main(["run", str(toy_file), "--seed", "2", "--out", str(out), "--quiet", "--overwrite"])
    assert Trace.load(out).seed == 2 and (out / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("where", ["file", "under_file"])
def test_out_that_is_or_lies_under_a_file_is_one_line(tmp_path, robofleet_bin, where):
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    out = blocker if where == "file" else blocker / "sub"
    result = run_cli(robofleet_bin, "run", "avoidance/circle_swap", "--out", out, "--quiet")
    assert_one_line_error(result, "--out: expected a directory", "is a file")
    result = run_cli(robofleet_bin, "sweep", "buavc_noise", "--out", out, "--quiet")
    assert_one_line_error(result, "store: expected a directory", "is a file")


def test_the_catalogue_refuses_an_unknown_kind():
    from robofleet.core.errors import ConfigError

    with pytest.raises(ConfigError, match="kind: expected one of"):
        robofleet.scenarios.list("scenario")
