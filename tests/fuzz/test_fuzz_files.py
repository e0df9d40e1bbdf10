"""Property-based fuzzing of every shipped scenario, sweep, plan and pattern file.

Each example mutates a shipped file (:mod:`fuzz_mutations`: wrong types, NaN, ±inf,
huge or negative numbers, deleted, renamed and unknown keys, nesting, repeated lists,
several at once) and runs ``robofleet validate`` on it in this process. The property:

* either a clean refusal: exit status 2 and exactly one line on stderr,
  ``error: FILE: ...expected ..., received ...``, no traceback, no warning line;
* or a valid file: exit status 0, and then the scenario loads and runs (at a budget of
  a few steps, within a per-file time allowance) to a trace with finite positions, or
  is refused at run time with a one-line robofleet error.

Everything runs under a memory budget of 256 MiB, so a mutant that would need more
must be refused before it allocates. Examples are derandomized (seeded) and bounded.
"""

from __future__ import annotations

import contextlib
import io
import shutil
import time
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml
from fuzz_mutations import garbled, mutated, text
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import robofleet
from robofleet.cli.main import main
from robofleet.core.budget import MEMORY_BUDGET_VARIABLE
from robofleet.core.errors import RobofleetError
from robofleet.scenarios import catalogue, family_of

BUDGET = "256MiB"
RUN_STEPS = 3
RUN_SECONDS_PER_FILE = 1.0  # the first valid mutant of each file always runs; more until this is spent
FUZZ = settings(max_examples=12, derandomize=True, database=None, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture, HealthCheck.data_too_large])
run_seconds: dict[str, float] = {}


@pytest.fixture(scope="module", autouse=True)
def small_memory_budget():
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(MEMORY_BUDGET_VARIABLE, BUDGET)
        yield


@pytest.fixture(scope="module")
def shipped_copy(tmp_path_factory) -> Path:
    """A copy of the shipped scenario and sweep folders (mutants are written beside the
    files they name, so relative plan and pattern paths resolve)."""
    root = tmp_path_factory.mktemp("fuzz")
    shutil.copytree(catalogue.folder("scenarios"), root / "scenarios")
    shutil.copytree(catalogue.folder("sweeps"), root / "sweeps")
    return root


def validate(path: Path) -> tuple[int, list[str]]:
    """``robofleet validate PATH`` in this process: exit status and stderr lines."""
    err = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        try:
            main(["validate", str(path)])
            code = 0
        except SystemExit as exc:
            code = exc.code
    return code, [line for line in err.getvalue().splitlines() if line.strip()]


def assert_clean(path: Path, code: int, lines: list[str], done: list[str]) -> None:
    """A one-line refusal naming the file, or success with at most the file's own warnings."""
    if code == 0:
        assert all(line.startswith(f"warning: {path}") for line in lines), (done, lines)
        return
    assert code == 2, (done, code, lines)
    assert len(lines) == 1, (done, lines)
    line = lines[0]
    assert line.startswith(f"error: {path}") and "Traceback" not in line, (done, line)
    assert "expected" in line and "received" in line and "<mapping>" not in line, (done, line)


def run_briefly(path: Path, key: str) -> None:
    """Load the valid mutant at a budget of a few steps and run it (within the allowance)."""
    if run_seconds.get(key, 0.0) > RUN_SECONDS_PER_FILE:
        return
    started = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # numpy overflow / invalid value: never silent
        try:
            spec = robofleet.load_scenario(path)
            spec = robofleet.load_scenario(path, {family_of(spec).budget: RUN_STEPS})
            trace = robofleet.simulate(spec, seed=1)
        except RobofleetError as exc:  # e.g. the short budget itself, or an infeasible instance
            assert "\n" not in str(exc), str(exc)
        else:
            assert np.all(np.isfinite(trace.positions)), "NaN or infinite positions in a trace"
            trace.summary()
    run_seconds[key] = run_seconds.get(key, 0.0) + time.perf_counter() - started


def check_mutant(path: Path, mapping: object, done: list[str], key: str, run: bool = True) -> None:
    path.write_text(yaml.safe_dump(mapping, allow_unicode=True, sort_keys=False))
    code, lines = validate(path)
    assert_clean(path, code, lines, done)
    if code == 0 and run:
        run_briefly(path, key)


@pytest.mark.parametrize("name", catalogue.names())
@FUZZ
@given(data=st.data())
def test_mutated_scenarios_are_refused_in_one_line_or_run(name, shipped_copy, data):
    source = shipped_copy / "scenarios" / f"{name}.yaml"
    mutant, done = data.draw(mutated(yaml.safe_load(source.read_text()), offset=zlib.crc32(name.encode())), label="mutations")
    check_mutant(source.with_name(f"{source.stem}.mutant.yaml"), mutant, done, name)


@pytest.mark.parametrize("name", catalogue.names())
@settings(FUZZ, max_examples=3)
@given(data=st.data())
def test_garbled_scenario_files_are_refused_in_one_line_or_run(name, shipped_copy, data):
    source = shipped_copy / "scenarios" / f"{name}.yaml"
    garbage, done = data.draw(garbled(source.read_bytes()), label="garbled")
    path = source.with_name(f"{source.stem}.garbled.yaml")
    path.write_bytes(garbage)
    code, lines = validate(path)
    assert_clean(path, code, lines, done)
    if code == 0:
        run_briefly(path, name)


@pytest.mark.parametrize("name", catalogue.names("sweeps"))
@settings(FUZZ, max_examples=3)
@given(data=st.data())
def test_mutated_sweeps_are_refused_in_one_line_or_valid(name, shipped_copy, data):
    source = shipped_copy / "sweeps" / f"{name}.yaml"
    mutant, done = data.draw(mutated(yaml.safe_load(source.read_text()), offset=zlib.crc32(name.encode()), repeat_limit=3),
                             label="mutations")
    check_mutant(source.with_name(f"{source.stem}.mutant.yaml"), mutant, done, name, run=False)


PLAN_SCENARIO = "coordination/fig2_three_robots"
cells = st.one_of(text, st.sampled_from(["-1", "0.5", "1e9", "1e400", "nan", "inf", "7", "100000000"]))


@st.composite
def mutated_plan(draw: st.DrawFn, rows: list[list[str]]) -> tuple[list[list[str]], list[str]]:
    """The plan's rows with cells replaced, rows dropped, repeated or cut short, the header broken."""
    rows = [list(r) for r in rows]
    done = []
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(rows) - 1)) if rows else 0
        operation = draw(st.sampled_from(["cell", "cell", "drop", "repeat", "short", "long", "truncate"]))
        if not rows:
            break
        if operation == "cell":
            j = draw(st.integers(0, len(rows[i]) - 1)) if rows[i] else 0
            if rows[i]:
                rows[i][j] = draw(cells)
        elif operation == "drop":
            rows.pop(i)
        elif operation == "repeat":
            rows.insert(i, list(rows[i]))
        elif operation == "short":
            rows[i] = rows[i][:-1]
        elif operation == "long":
            rows[i] = [*rows[i], "1"]
        else:
            rows = rows[: i + 1]
        done.append(f"{operation} row {i}")
    return rows, done


@FUZZ
@given(data=st.data())
def test_mutated_plans_are_refused_in_one_line_or_run(shipped_copy, data):
    scenario = shipped_copy / "scenarios" / f"{PLAN_SCENARIO}.yaml"
    plan = scenario.with_name("fig2_plan.csv")
    original = getattr(test_mutated_plans_are_refused_in_one_line_or_run, "original", None) or plan.read_text()
    test_mutated_plans_are_refused_in_one_line_or_run.original = original
    rows, done = data.draw(mutated_plan([line.split(",") for line in original.splitlines()]), label="plan")
    try:
        plan.write_text("\n".join(",".join(r) for r in rows) + "\n")
        code, lines = validate(scenario)
        if code == 2:  # a bad plan is reported naming the scenario (and the plan file inside)
            assert len(lines) == 1 and lines[0].startswith(f"error: {scenario}") and "expected" in lines[0], (done, lines)
        else:
            assert code == 0 and not lines, (done, code, lines)
            run_briefly(scenario, PLAN_SCENARIO + ".csv")
    finally:
        plan.write_text(original)


PATTERN_SCENARIO = "flocking/shared_axes_column"


@FUZZ
@given(data=st.data())
def test_mutated_pattern_files_are_refused_in_one_line_or_run(shipped_copy, data):
    scenario = shipped_copy / "scenarios" / f"{PATTERN_SCENARIO}.yaml"
    pattern = scenario.parent / "patterns" / "column.yaml"
    original = getattr(test_mutated_pattern_files_are_refused_in_one_line_or_run, "original", None) or pattern.read_text()
    test_mutated_pattern_files_are_refused_in_one_line_or_run.original = original
    mutant, done = data.draw(mutated(yaml.safe_load(original)), label="mutations")
    try:
        pattern.write_text(yaml.safe_dump(mutant))
        code, lines = validate(scenario)
        assert_clean(scenario, code, lines, done)
        if code == 0:
            run_briefly(scenario, PATTERN_SCENARIO + ".pattern")
    finally:
        pattern.write_text(original)
