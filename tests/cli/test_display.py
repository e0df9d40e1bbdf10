"""The CLI's tables show values as ``summary.json`` holds them: a missing value reads ``null``."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from rich.console import Console

from robofleet.cli.display import format_value, frame_table, key_value_table
from robofleet.cli.main import main


def rendered(table) -> str:
    console = Console(width=200, record=True, file=open("/dev/null", "w"))  # noqa: SIM115 - closed with the console
    console.print(table)
    console.file.close()
    return console.export_text()


@pytest.mark.parametrize("missing", [None, math.nan, math.inf, -math.inf, np.float32("nan"), np.float64("inf"), pd.NA, pd.NaT])
def test_missing_values_read_null(missing):
    assert format_value(missing) == "null"


def test_values_inside_lists_and_mappings_read_as_json():
    assert format_value([1.0, math.nan]) == "[1.0, null]"
    assert format_value({"a": math.inf, "b": 2}) == '{"a": null, "b": 2}'
    assert format_value(np.array([0.5, np.nan])) == "[0.5, null]"
    assert format_value(1.23456) == "1.235" and format_value(np.int64(3)) == "3" and format_value("x") == "x"


def test_summary_and_means_tables_print_null_where_the_json_has_null():
    text = rendered(key_value_table({"a": None, "b": math.nan, "c": math.inf, "d": 1.5}, "t"))
    rows = {line.split()[1]: line.split()[3] for line in text.splitlines() if line.startswith("│")}
    assert rows == {"a": "null", "b": "null", "c": "null", "d": "1.5"}
    frame = pd.DataFrame({"n": [1, 2], "rate": [0.25, np.nan], "time": [np.inf, 3.0]})
    text = rendered(frame_table(frame, "means", leading=1))
    assert "null" in text and not {"nan", "inf", "None", "<NA>"} & set(text.replace("│", " ").split())


def test_run_table_matches_its_summary_json(tmp_path, capsys):
    out = tmp_path / "run"
    main(["run", "avoidance/circle_swap", "--seed", "1", "--out", str(out), "--set", "max_steps=4"])
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    missing = [key for key, value in summary.items() if value is None]
    assert "min_obstacle_distance" in missing  # no obstacles: inf in the trace, null in the JSON
    table = {line.split()[1]: line.split()[3] for line in printed.splitlines() if line.startswith("│")}
    for key in missing:
        assert table[key] == "null", key
    assert not {"nan", "inf", "None"} & set(table.values())
