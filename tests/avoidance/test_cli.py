"""The generic commands on avoidance scenarios and reproductions (``run``, ``check``,
``reproduce buavc-models``)."""

import json

import pytest
import yaml

from robofleet.cli.main import main
from robofleet.core.trace import CORE_SUMMARY_KEYS


def test_run_writes_the_trace_and_a_summary_led_by_the_core_keys(tmp_path, capsys):
    scenario = tmp_path / "short.yaml"
    scenario.write_text(yaml.safe_dump({"family": "avoidance", "max_steps": 15, "robots": {"n": 3, "layout": {"kind": "circle", "radius": 3.0}}}))
    main(["run", str(scenario), "--seed", "3", "--out", str(tmp_path / "out"), "--quiet"])
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert list(summary)[: len(CORE_SUMMARY_KEYS)] == list(CORE_SUMMARY_KEYS)
    assert summary["seed"] == 3 and summary["family"] == "avoidance" and summary["n_steps"] == 15
    assert {"trace.npz", "trace.json"} <= {p.name for p in (tmp_path / "out").iterdir()}
    assert "(seed 3)" in capsys.readouterr().out


def test_check_prints_one_line_per_paper_condition(capsys):
    main(["check", "avoidance/three_boxes"])
    lines = capsys.readouterr().out.strip().splitlines()
    assert "Zhu, Brito & Alonso-Mora 2022" in lines[0]
    assert any(line.startswith("collision probability ≤ δ per pair and step") and ": yes" in line for line in lines[1:])
    assert any(line.startswith("robots start inside their own B-UAVC") for line in lines[1:])


def test_reproduce_buavc_models_lists_its_options(capsys):
    main(["reproduce", "buavc-models", "--help"])
    out = capsys.readouterr().out
    for option in ("--seeds", "--budget", "--executor", "--scheduler", "--workers", "--out"):
        assert option in out


def test_unknown_reproduction_is_rejected_in_one_line(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "buavc-hovercraft"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "buavc-hovercraft" in err[0] and "buavc-models" in err[0]
