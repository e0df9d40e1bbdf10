"""``validate`` checks everything ``run`` reads (sweeps point by point, plan and pattern
files), and malformed files of every kind are one line naming the file, exit status 2."""

from __future__ import annotations

import shutil

import pytest
import yaml

from robofleet.cli.main import main
from robofleet.scenarios import catalogue

ALIAS_BOMB = b"a: &a [x, x, x, x, x, x, x, x, x, x]\n" + b"".join(
    f"{b}: &{b} [{', '.join([f'*{a}'] * 10)}]\n".encode() for a, b in zip("abcdef", "bcdefg"))


def refused(capsys, *args):
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    lines = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and len(lines) == 1 and lines[0].startswith("error: "), lines
    assert "Traceback" not in lines[0] and "warning" not in lines[0].lower(), lines
    return lines[0]


def test_validate_takes_a_shipped_sweep_and_run_points_to_the_sweep_command(capsys):
    main(["validate", "buavc_noise"])
    assert capsys.readouterr().out.strip() == f"ok: {catalogue.path('buavc_noise', 'sweeps')} (sweep: 12 grid points × 20 seeds = 240 runs)"
    line = refused(capsys, "run", "buavc_noise")
    assert "expected a scenario file, received the sweep buavc_noise" in line and "robofleet sweep" in line


def test_a_sweep_with_a_bad_grid_value_is_refused_by_validate_and_sweep(tmp_path, capsys):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"scenario": "avoidance/circle_swap", "grid": {"robots.radius": [0.1, -1]}, "seeds": 2}))
    for command in ("validate", "sweep"):
        line = refused(capsys, command, sweep, *(["--out", tmp_path / "store"] if command == "sweep" else []))
        assert line.startswith(f"error: {sweep}: grid robots.radius=-1 → ") and "robots.radius" in line, line
    assert not (tmp_path / "store").exists()


def test_sweeps_refuse_repeated_grid_values_and_oversized_seed_counts(tmp_path, capsys):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"scenario": "avoidance/circle_swap", "grid": {"delta": [0.1, 0.1]}, "seeds": 2}))
    assert "grid.delta: expected distinct values" in refused(capsys, "validate", sweep)
    sweep.write_text(yaml.safe_dump({"scenario": "avoidance/circle_swap", "seeds": 10**19}))
    assert "seeds: expected a number of seeds in [1, 1,000,000]" in refused(capsys, "validate", sweep)
    sweep.write_text(yaml.safe_dump({"scenario": "x" * 5000, "seeds": 1}))
    assert "scenario: expected a file or a shipped scenario name" in refused(capsys, "validate", sweep)


def test_a_missing_or_bad_pattern_file_is_refused_at_validation(tmp_path, capsys):
    source = catalogue.path("flocking/shared_axes_column")
    shutil.copytree(source.parent, tmp_path / "flocking")
    scenario = tmp_path / "flocking" / source.name
    pattern = tmp_path / "flocking" / "patterns" / "column.yaml"
    pattern.write_text("points: [[-40, 0], [-40, 0]]\n")
    line = refused(capsys, "validate", scenario)
    assert line.startswith(f"error: {scenario}: pattern.path: {pattern}: points: expected distinct points"), line
    pattern.unlink()
    line = refused(capsys, "validate", scenario)
    assert line.startswith(f"error: {scenario}: ") and "a readable pattern file" in line, line


@pytest.mark.parametrize("content, expected", [
    (b"family: avoidance\nname: caf\xe9\n", "expected a UTF-8 text file, received a byte b'\\xe9' at offset"),
    (b"family: avoidance\nfamily: search\n", "line 2: expected valid YAML, received \"the key 'family' given twice\""),
    (b"family: avoidance\nmax_steps: 1" + b"0" * 5000 + b"\n", "expected valid YAML of reasonable size"),
    (ALIAS_BOMB, "expected at most 2,000,000 values"),
    (b"a: &a [*a]\n", "expected data that does not contain itself"),
    (b"family: avoidance\nmax_steps: 9223372036854775808\n", "max_steps: expected a finite number of magnitude at most 1e+09"),
    (b"family: avoidance\ndelta: .nan\n", "delta: expected a finite number, received nan"),
    (b"family: avoidance\nworkspace: {obstacles: .nan}\n", "workspace.obstacles: expected a valid list"),
])
def test_malformed_files_are_one_line_for_validate_and_run(content, expected, tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_bytes(content)
    for command in ("validate", "run"):
        line = refused(capsys, command, path, *(["--out", tmp_path / "out"] if command == "run" else []))
        assert line.startswith(f"error: {path}: ") and expected in line, line


def test_unusable_paths_on_the_command_line_are_one_line(tmp_path, capsys):
    assert "--out: expected a usable directory path" in refused(capsys, "run", "avoidance/circle_swap", "--quiet", "--out", "y" * 5000)
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"scenario": "avoidance/circle_swap", "overrides": {"max_steps": 2}, "seeds": 1}))
    assert "store: expected a usable directory path" in refused(capsys, "sweep", sweep, "--executor", "serial", "--quiet", "--out", "y" * 5000)
    assert "expected a file or a shipped scenario name" in refused(capsys, "validate", "x" * 5000)
    assert "expected a readable YAML file" in refused(capsys, "validate", "a\x00b.yaml")
