"""``--set KEY=VALUE`` on ``run``, ``validate`` and ``check``: dotted overrides applied to the
scenario before validation, refused exactly as the same value in the file is, naming the
``--set`` argument."""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest
import yaml

from robofleet import load_scenario
from robofleet.cli.main import main
from robofleet.core.config import set_path
from robofleet.core.errors import ScenarioError
from robofleet.core.trace import Trace
from robofleet.scenarios import path as shipped_path


def error_of(argv, capsys) -> str:
    """The one line ``main(argv)`` writes to stderr when it exits with status 2."""
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: "), err
    return err.strip()


@pytest.fixture
def circle_swap(tmp_path):
    """A copy of the shipped circle swap (its message names this file)."""
    return shutil.copy(shipped_path("avoidance/circle_swap"), tmp_path / "circle_swap.yaml")


def test_run_applies_every_set_and_records_it(tmp_path, capsys):
    out = tmp_path / "run"
    main(["run", "avoidance/circle_swap", "--seed", "3", "--out", str(out), "--quiet",
          "--set", "max_steps=6", "--set", "robots.n=4", "--set", "robots.layout={kind: circle, radius: 3.0}"])
    assert "(seed 3)" in capsys.readouterr().out
    trace = Trace.load(out)
    assert trace.positions.shape[1] == 4 and len(trace.positions) <= 7
    assert trace.metadata["max_steps"] == 6
    expected = load_scenario("avoidance/circle_swap", overrides={"max_steps": 6, "robots.n": 4,
                                                                 "robots.layout": {"kind": "circle", "radius": 3.0}})
    assert json.loads((out / "summary.json").read_text())["n_robots"] == expected.robots.n == 4


def test_validate_and_check_take_set(capsys):
    main(["validate", "avoidance/circle_swap", "--set", "delta=0.2", "--set", "workspace.bounds=[-8, -5, 8, 5]"])
    assert capsys.readouterr().out.strip().endswith("circle_swap.yaml --set delta=0.2 --set workspace.bounds=[-8, -5, 8, 5] (avoidance)")
    main(["check", "avoidance/circle_swap", "--set", "delta=0.2"])
    assert "δ = 0.2" in capsys.readouterr().out


def test_a_list_element_is_set_by_its_index(tmp_path, capsys):
    main(["validate", "avoidance/heterogeneous", "--set", "teams.0.sigma=0.05"])
    assert capsys.readouterr().out.startswith("ok: ")


@pytest.mark.parametrize(("key", "value", "parsed"), [
    ("max_steps", "-1", -1),                      # out of range
    ("robots.n", "abc", "abc"),                   # wrong type
    ("robots.nn", "3", 3),                        # unknown key
    ("robots.n", "300", 300),                     # more robots than the layout holds
    ("workspace.bounds", "[0, 0]", [0, 0]),       # a list of the wrong length
    ("family", "nope", "nope"),                   # unknown family
])
def test_a_bad_set_gets_the_files_error_naming_the_argument(circle_swap, tmp_path, capsys, key, value, parsed):
    data = yaml.safe_load(circle_swap.read_text())
    set_path(data, key, parsed)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    in_file = error_of(["validate", str(bad)], capsys)
    for command in ("validate", "check", "run"):
        out = ["--out", str(tmp_path / "o")] if command == "run" else []
        from_set = error_of([command, str(circle_swap), "--set", f"{key}={value}", *out], capsys)
        assert from_set == f"error: --set {key}={value}: {circle_swap}" + in_file.removeprefix(f"error: {bad}")
    assert not (tmp_path / "o").exists()


def test_assignments_that_break_the_scenario_together_are_all_named(circle_swap, capsys):
    line = error_of(["validate", str(circle_swap), "--set", "robots.layout.radius=40", "--set", "delta=0.2"], capsys)
    assert line.startswith("error: --set robots.layout.radius=40 --set delta=0.2: ") and "inside the workspace" in line


def test_a_file_invalid_on_its_own_is_reported_as_the_file(circle_swap, capsys):
    circle_swap.write_text(circle_swap.read_text().replace("delta: 0.1", "delta: 7"))
    line = error_of(["validate", str(circle_swap), "--set", "max_steps=10"], capsys)
    assert line.startswith(f"error: {circle_swap}: delta: ") and "--set" not in line


@pytest.mark.parametrize(("argument", "words"), [
    ("robots.n", ["--set: expected KEY=VALUE", "'robots.n'"]),
    ("=3", ["--set: expected KEY=VALUE", "'=3'"]),
    ("robots..n=3", ["dotted field path", "'robots..n=3'"]),
    ("robots.n=[1, 2", ["--set robots.n=[1, 2: expected VALUE in YAML", "'[1, 2'"]),
    ("teams.7.sigma=0.1", ["--set teams.7.sigma=0.1: ", "heterogeneous.yaml: teams: expected an index below 2", "'7'"]),
])
def test_malformed_set_arguments_are_one_line(capsys, argument, words):
    line = error_of(["validate", "avoidance/heterogeneous", "--set", argument], capsys)
    for word in words:
        assert word in line


def test_a_field_set_twice_and_set_on_a_sweep_are_refused(capsys):
    line = error_of(["validate", "avoidance/circle_swap", "--set", "robots.n=3", "--set", "robots.n=4"], capsys)
    assert "robots.n twice (--set robots.n=3 and --set robots.n=4)" in line
    line = error_of(["validate", "buavc_noise", "--set", "delta=0.2"], capsys)
    assert line.startswith("error: --set: expected a scenario, received the sweep buavc_noise")


def test_the_command_line_exits_2_without_traceback(robofleet_bin, tmp_path):
    result = subprocess.run([str(robofleet_bin), "run", "avoidance/circle_swap", "--set", "robots.radius=-1", "--out", str(tmp_path / "o")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "Traceback" not in result.stderr + result.stdout
    assert result.stderr.splitlines() == [result.stderr.strip()]
    assert result.stderr.startswith("error: --set robots.radius=-1: ") and ": robots.radius: expected" in result.stderr


FIELDS = ["max_steps", "delta", "dt", "goal_tolerance", "local_box", "robots.n", "robots.radius", "robots.sigma",
          "robots.v_max", "robots.layout.radius", "robots.layout.kind", "workspace.bounds", "robots.nn", "method"]
VALUES = [-1, 0, 0.05, 0.3, 3, 12, 1e12, "abc", "orca", "circle", [1, 2], [-6, -6, 6, 6], None, True]


def test_random_single_sets_match_the_python_api_exactly(circle_swap, capsys):
    """Seeded random field × value pairs: ``--set`` accepts exactly what
    ``load_scenario(file, overrides)`` accepts, and refuses the rest with its message, naming the argument."""
    rng = np.random.default_rng(25)
    for _ in range(40):
        key, value = FIELDS[rng.integers(len(FIELDS))], VALUES[rng.integers(len(VALUES))]
        argument = f"{key}={json.dumps(value)}"
        try:
            load_scenario(str(circle_swap), overrides={key: value})
        except ScenarioError as exc:
            assert error_of(["validate", str(circle_swap), "--set", argument], capsys) == f"error: --set {argument}: {exc}"
        else:
            main(["validate", str(circle_swap), "--set", argument])
            assert capsys.readouterr().out.startswith(f"ok: {circle_swap} --set {argument} (avoidance)")
