"""The memory budget: runs that would not fit are refused by ``validate`` and ``run``
before anything is allocated, naming the robot count, the step budget and the estimate;
the estimate bounds what a run records; the budget is settable by the environment
variable and ``--memory-budget``."""

from __future__ import annotations

import os
import re
import subprocess

import numpy as np
import pytest
import yaml

import robofleet
from robofleet.cli.main import main
from robofleet.core.budget import (
    MAX_BUDGET,
    MEMORY_BUDGET_VARIABLE,
    MIN_BUDGET,
    RunSize,
    check_run_size,
    format_bytes,
    memory_budget,
    parse_size,
)
from robofleet.core.errors import ConfigError, RobofleetError, ScenarioError
from robofleet.core.recorder import Recorder
from robofleet.scenarios import catalogue, family_of

ONE_PER_FAMILY = ["avoidance/circle_swap", "coordination/x_corridor_5_tff", "flocking/wedge_async", "search/fig7"]


def run_main(capsys, *args):
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    return info.value.code, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("name", ONE_PER_FAMILY)
@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_run_beyond_the_budget_is_refused_by_validate_and_run(name, command, capsys, tmp_path):
    extra = ["--out", tmp_path / "run", "--quiet"] if command == "run" else []
    code, lines = run_main(capsys, command, name, "--memory-budget", "1MiB", *extra)
    assert code == 2 and len(lines) == 1, lines
    line = lines[0]
    path = str(catalogue.path(name))
    assert line.startswith(f"error: {path}: ") and "memory budget of 1 MiB" in line, line
    assert " robots × " in line and " steps ≈ " in line and "--memory-budget" in line, line
    assert not (tmp_path / "run").exists()  # refused before anything was written or allocated


def test_huge_counts_and_step_budgets_are_refused_in_every_family_without_allocating():
    cases = {"avoidance/circle_swap": {"max_steps": 10**9}, "coordination/x_corridor_5_tff": {"robots.count": 10**9},
             "flocking/wedge_async": {"duration": 1e9}, "search/fig7": {"max_steps": 10**9}}
    for name, overrides in cases.items():
        with pytest.raises(ScenarioError, match="memory budget of 4 GiB") as info:
            robofleet.load_scenario(name, overrides)
        field = next(iter(overrides))
        assert field.split(".")[-1] in info.value.field or field in str(info.value), str(info.value)


def test_the_environment_variable_sets_the_budget_and_a_bad_value_is_one_line(robofleet_bin, monkeypatch):
    monkeypatch.setenv(MEMORY_BUDGET_VARIABLE, "2MiB")
    assert memory_budget() == 2 * 2**20
    with pytest.raises(ScenarioError, match="memory budget of 2 MiB"):
        robofleet.load_scenario("avoidance/ten_boxes")
    result = subprocess.run([str(robofleet_bin), "validate", "avoidance/circle_swap"], capture_output=True, text=True,
                            env={**os.environ, MEMORY_BUDGET_VARIABLE: "lots"}, timeout=120, check=False)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.strip().splitlines() == [
        f"error: {MEMORY_BUDGET_VARIABLE}: expected a size such as 4GiB, 512MiB or 2000000000 (bytes) between 1MiB and 1PiB, received 'lots'"]


def test_the_cli_option_holds_for_one_command_only(capsys, monkeypatch):
    monkeypatch.delenv(MEMORY_BUDGET_VARIABLE, raising=False)
    code, _ = run_main(capsys, "validate", "avoidance/circle_swap", "--memory-budget", "1MiB")
    assert code == 2
    main(["validate", "avoidance/circle_swap"])  # the default budget again
    assert memory_budget() == 4 * 2**30
    code, lines = run_main(capsys, "validate", "avoidance/circle_swap", "--memory-budget", "0.5MiB")
    assert code == 2 and lines[0].startswith("error: --memory-budget: expected a size"), lines


@pytest.mark.parametrize("text, size", [("4GiB", 4 * 2**30), ("512 MB", 512 * 10**6), ("2e9", 2 * 10**9), ("3000000", 3_000_000),
                                        ("1.5gib", int(1.5 * 2**30))])
def test_sizes_parse(text, size):
    assert parse_size(text) == size


@pytest.mark.parametrize("text", ["", "4 GiBs", "-1GiB", "1e400", "nan", "1KiB", "2PiB", True, None, 3.5])
def test_bad_sizes_are_refused(text):
    with pytest.raises(ConfigError, match="expected a size"):
        parse_size(text)


@pytest.mark.parametrize("name", [*ONE_PER_FAMILY, "avoidance/ten_boxes", "avoidance/diff_drive", "avoidance/heterogeneous",
                                  "coordination/fig2_three_robots", "flocking/random_async", "search/failure_injection"])
def test_the_estimate_bounds_what_a_run_records(name):
    spec = robofleet.load_scenario(name)
    short = robofleet.load_scenario(spec.source, {family_of(spec).budget: 4})
    trace = robofleet.simulate(short, seed=3)
    recorded = sum(array.nbytes for array in trace.arrays.values())
    estimate = short.run_size()
    assert recorded <= estimate.nbytes, f"{name}: recorded {format_bytes(recorded)} > estimated {estimate.describe()}"


def test_the_recorder_refuses_arrays_beyond_the_budget_before_allocating(monkeypatch):
    monkeypatch.setenv(MEMORY_BUDGET_VARIABLE, "1MiB")
    rec = Recorder(max_steps=1000, n_robots=10)
    rec.state("positions", (10, 2))  # 160 KB
    with pytest.raises(ConfigError, match=r"max_steps, n_robots: .*memory budget of 1 MiB.* array 'estimates'"):
        rec.step("estimates", (10, 100))  # 8 MB more
    assert "estimates" not in rec.arrays()
    with pytest.raises(ConfigError, match="memory budget"):
        Recorder(max_steps=10**9, n_robots=1)


def test_a_sweep_is_validated_point_by_point_against_the_budget(tmp_path, capsys):
    sweep = tmp_path / "big.yaml"
    sweep.write_text(yaml.safe_dump({"scenario": "avoidance/circle_swap", "grid": {"max_steps": [100, 10**8]}, "seeds": 2}))
    code, lines = run_main(capsys, "validate", sweep)
    assert code == 2 and len(lines) == 1
    assert lines[0].startswith(f"error: {sweep}: grid max_steps=100000000 → ") and "memory budget" in lines[0], lines
    sweep.write_text(yaml.safe_dump({"scenario": "avoidance/circle_swap", "grid": {"max_steps": [100, 200]}, "seeds": 2}))
    main(["validate", str(sweep)])
    assert capsys.readouterr().out.strip() == f"ok: {sweep} (sweep: 2 grid points × 2 seeds = 4 runs)"


def test_run_size_names_every_field_those_of_the_larger_part_first():
    assert RunSize(10, 2, 8, "max_steps", "robots.n").field == "robots.n, max_steps"
    grid = RunSize(10, 2, 8, "max_steps", "robots.count", extra_bytes=10**9, extra_what="grid", extra_field="grid.a, robots.count")
    assert grid.field == "grid.a, robots.count, max_steps" and "grid ≈ 954 MiB" in grid.describe()
    small = RunSize(10**6, 2, 8, "max_steps", "robots.count", extra_bytes=10, extra_field="grid.a", row_fields="record_every")
    assert small.fields == ("robots.count", "max_steps", "record_every", "grid.a")
    with pytest.raises(ScenarioError, match=r"^f.yaml: grid.a, robots.count, max_steps: expected a run that fits the memory budget"):
        check_run_size(grid, "f.yaml") if memory_budget() < 10**9 else check_run_size(
            RunSize(10, 2, 8, "max_steps", "robots.count", extra_bytes=10**13, extra_field="grid.a, robots.count"), "f.yaml")
    assert np.isclose(grid.nbytes, 11 * 2 * 8 + 11 * 8 + 10**9)


# -- every unit the message names is accepted ----------------------------------------------
def test_every_size_the_message_names_and_every_unit_it_prints_is_accepted(capsys):
    with pytest.raises(ConfigError) as info:
        parse_size("lots")
    named = re.findall(r"\b\d+[A-Za-z]+\b|\b\d{4,}\b", str(info.value).split(", received")[0])
    assert {"4GiB", "512MiB", "2000000000", "1MiB", "1PiB"} <= set(named), named
    for text in named:
        number, unit = re.fullmatch(r"(\d+)([A-Za-z]*)", text).groups()
        for variant in {text, text.lower(), text.upper(), f"{number} {unit}", f" {number}{unit.lower()} "}:
            assert parse_size(variant) == parse_size(text), variant
    assert parse_size("1PiB") == MAX_BUDGET and parse_size("1MiB") == MIN_BUDGET
    for nbytes in (MIN_BUDGET, 3 * 2**20, 5 * 2**30, 7 * 2**40, MAX_BUDGET):  # what the messages print reads back
        assert parse_size(format_bytes(nbytes)) == nbytes, format_bytes(nbytes)
    for text in ("1PiB", "1 pib", "1024tib", "8388608 bytes"):  # the command line takes them too
        main(["validate", "avoidance/circle_swap", "--memory-budget", text])
    for unit, factor in {"B": 1, "bytes": 1, "kB": 10**3, "KiB": 2**10, "MB": 10**6, "GB": 10**9, "TB": 10**12, "TiB": 2**40,
                         "PB": 10**15, "P": 10**15}.items():
        count = -(-MIN_BUDGET // factor)
        assert parse_size(f"{count}{unit}") == count * factor, unit


# -- a refused run names every field that drives its size -----------------------------------
SIZE_SCENARIOS = [("avoidance/circle_swap", {}), ("avoidance/circle_swap", {"robots.n": 40, "record_cells": True, "local_box": 0.5}),
                  ("avoidance/heterogeneous", {}), ("avoidance/ten_boxes", {}), ("coordination/x_corridor_5_tff", {}),
                  ("coordination/fig2_three_robots", {}), ("flocking/wedge_async", {}), ("flocking/random_async", {}),
                  ("flocking/wedge_fsync_straight", {}), ("search/fig7", {}),
                  ("search/failure_injection", {})]


def scaled(value):
    """``value`` with every number doubled (0 becomes 1)."""
    if isinstance(value, list):
        return [scaled(v) for v in value]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return type(value)(2 * value or 1)
    return value


def numeric_fields(value, path=""):
    """``(dotted path, changed value)`` for every number and list of numbers in a dumped spec."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield from numeric_fields(item, f"{path}.{key}" if path else key)
    elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        for index, item in enumerate(value):
            yield from numeric_fields(item, f"{path}.{index}")
    elif isinstance(value, (int, float, list)) and not isinstance(value, bool) and value != []:
        yield path, scaled(value)


def without_indices(path: str) -> str:
    return ".".join(part for part in path.split(".") if not part.isdigit())


def named_by(path: str, fields) -> bool:
    """Whether one of ``fields`` is ``path`` or a block holding it (list indices ignored)."""
    path = without_indices(path)
    return any(path == f or path.startswith(f + ".") for f in map(without_indices, fields))


@pytest.mark.parametrize("name, base", SIZE_SCENARIOS)
def test_a_refused_run_names_every_field_that_drives_its_size(name, base, monkeypatch):
    """Double every number of the scenario, one at a time: each change that changes the
    estimate is of a field the scenario's refusal names."""
    monkeypatch.setenv(MEMORY_BUDGET_VARIABLE, "1PiB")
    spec = robofleet.load_scenario(name, base)
    size, named, changed = spec.run_size().nbytes, spec.run_size().field.split(", "), 0
    for path, value in numeric_fields(spec.model_dump(mode="json")):
        try:
            other = robofleet.load_scenario(name, {**base, path: value})
        except RobofleetError:
            continue  # the change makes the scenario invalid
        if other.run_size().nbytes != size:
            changed += 1
            assert named_by(path, named), f"{name}: {path} changes the estimate; named: {named}"
    assert changed >= 1


@pytest.mark.parametrize("name, overrides, named", [
    ("flocking/wedge_async", {"followers.count": 10**7}, ["followers.count", "duration", "scheduler.cycle_min"]),
    ("flocking/random_async", {"pattern.n_points": 10**7}, ["pattern.n_points", "duration"]),
    ("flocking/wedge_async", {"duration": 1e9}, ["duration", "sample_dt", "scheduler.cycle_min"]),
    ("avoidance/circle_swap", {"deadlock.window": 10**8}, ["deadlock.window", "robots.n", "max_steps"]),
    ("avoidance/heterogeneous", {"teams.0.n": 10**6}, ["teams.n", "max_steps"]),
    ("coordination/x_corridor_5_tff", {"robots.count": 10**5}, ["robots.count", "simulation.max_steps", "planner.max_steps"]),
    ("coordination/x_corridor_5_tff", {"planner.grid_spacing": 1e-4}, ["planner.grid_spacing", "workspace", "robots.count"]),
    ("search/fig7", {"robots.count": 10**6}, ["robots.count", "max_steps", "grid.a"]),
    ("search/fig7", {"grid.a": 1e-4}, ["grid.a", "workspace", "robots.count"]),
])
def test_the_refusal_names_the_fields_of_each_family(name, overrides, named):
    with pytest.raises(ScenarioError, match="memory budget of 4 GiB") as info:
        robofleet.load_scenario(name, overrides)
    message = str(info.value)
    assert "\n" not in message
    listed = info.value.field.split(", ")
    assert all(field in listed for field in named) and f"{info.value.field}: expected" in message, message
