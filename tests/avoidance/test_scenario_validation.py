"""Every invalid scenario gives one clear line naming file, field, expectation, value."""

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

import robofleet
from robofleet import ScenarioError

BASE = yaml.safe_load(Path("scenarios/avoidance/three_boxes.yaml").read_text())


def with_change(path, value):
    data = yaml.safe_load(yaml.safe_dump(BASE))
    node = data
    keys = path.split(".")
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    return data


CASES = [
    ("robots.colour", "red", "robots.colour", "unknown field"),
    ("robots.n", "many", "robots.n", "integer"),
    ("robots.radius", 0.0, "robots.radius", "greater than 0"),
    ("robots.radius", -1.0, "robots.radius", "greater than 0"),
    ("delta", 1.0, "delta", "less than 1"),
    ("delta", 0.0, "delta", "greater than 0"),
    ("method", "magic", "method", "'buavc', 'bvc'"),
    ("robots.cov", [[0.01, 0.002], [0.0, 0.01]], "robots.cov", "symmetric"),
    ("robots.cov", [[0.01, 0.0], [0.0, -0.01]], "robots.cov", "positive semi-definite"),
    ("robots.cov", [[0.01, 0.0, 0.0]], "robots.cov", "2×2"),
    ("robots.layout", {"kind": "explicit", "starts": [[0, 0], [0.1, 0], [2, 2], [3, 3], [-3, 3]], "goals": [[1, 1], [2, -2], [-2, -2], [3, -3], [-3, -3]]}, "robots.layout.starts[0]", "2·radius"),
    ("robots.layout", {"kind": "explicit", "starts": [[-4, 1], [1, 1], [2, 2], [3, 2.5], [-3, 3]], "goals": [[1, 2], [2, -2], [-2, -2], [3, -3], [-3, -3]]}, "robots.layout.starts[0]", "from every obstacle"),
    ("robots.layout", {"kind": "explicit", "starts": [[9, 9], [1, 1], [2, 2], [3, 2.5], [-3, 3]], "goals": [[1, 2], [2, -2], [-2, -2], [3, -3], [-3, -3]]}, "robots.layout.starts[0]", "inside the workspace"),
    ("robots.layout", {"kind": "explicit", "starts": [[1, 1]], "goals": [[2, 2]]}, "robots.layout.starts", "5 starts"),
    ("robots.n", 500, "robots.n", "few enough robots"),
    ("workspace.obstacles", [{"vertices": [[0, 0], [2, 0], [1, 0.2], [1, 2]]}], "workspace.obstacles.0", "convex"),
    ("workspace.bounds", [5, 5, -5, -5], "workspace.bounds", "min < max"),
]


@pytest.mark.parametrize("path,value,field,expected", CASES)
def test_invalid_field_names_file_field_and_expectation(tmp_path, path, value, field, expected):
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(with_change(path, value)))
    with pytest.raises(ScenarioError) as err:
        robofleet.load_scenario(f)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(str(f)), msg
    assert field in msg, msg
    assert expected in msg, msg
    assert "received" in msg


def test_circle_too_crowded():
    with pytest.raises(ScenarioError, match="robots.n: expected at most"):
        robofleet.load_scenario({"robots": {"n": 80, "layout": {"kind": "circle", "radius": 4.0}}})


def test_yaml_syntax_and_missing_file(tmp_path):
    f = tmp_path / "broken.yaml"
    f.write_text("robots: [1, 2\n")
    with pytest.raises(ScenarioError, match="valid YAML"):
        robofleet.load_scenario(f)
    with pytest.raises(ScenarioError, match="readable YAML file"):
        robofleet.load_scenario(tmp_path / "missing.yaml")


def test_cli_reports_one_line_and_exit_status_2(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(with_change("robots.radius", -1)))
    exe = Path(sys.executable).parent / "robofleet"
    for cmd in (["validate", str(f)], ["run", str(f), "--out", str(tmp_path / "out")]):
        proc = subprocess.run([str(exe), *cmd], capture_output=True, text=True)
        assert proc.returncode == 2
        assert "Traceback" not in proc.stderr
        lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
        assert len(lines) == 1 and "robots.radius" in lines[0], proc.stderr


def test_shipped_scenarios_validate():
    for f in sorted(Path("scenarios/avoidance").glob("*.yaml")):
        spec = robofleet.load_scenario(f)
        assert spec.family == "avoidance" and spec.source == str(f)
