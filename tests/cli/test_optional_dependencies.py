"""A missing optional dependency is one line naming the extra to install, from ``validate``
as from ``run`` (the modules are hidden from a fresh interpreter)."""

from __future__ import annotations

import subprocess
import sys

import pytest
import yaml

from robofleet.core import extras

HIDE = "import sys; sys.modules.update({{{modules}}}); from robofleet.cli.main import main; main({args!r})"


def run_without(modules, *args):
    hidden = ", ".join(f"{m!r}: None" for m in modules)
    code = HIDE.format(modules=hidden, args=[str(a) for a in args])
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)


def assert_names_the_extra(result, extra):
    assert result.returncode == 2, result
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith("error: ") and f"pip install 'robofleet[{extra}]'" in lines[0], lines


@pytest.mark.parametrize("command, hidden", [("validate", ("casadi",)), ("run", ("daqp",))])
def test_mpc_scenarios_without_the_mpc_extra(command, hidden, tmp_path):
    result = run_without(hidden, command, "avoidance/quadrotors_3d", *(["--out", tmp_path / "r", "--quiet"] if command == "run" else []))
    assert_names_the_extra(result, "mpc")
    assert f"expected an installed {hidden[0]} " in result.stderr and "teams.0.model.controller" in result.stderr


def test_the_dask_executor_without_the_dask_extra(tmp_path):
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"scenario": "avoidance/circle_swap", "overrides": {"max_steps": 3}, "seeds": 1}))
    result = run_without(("distributed", "dask", "dask.distributed"), "sweep", sweep, "--executor", "dask", "--quiet",
                         "--out", tmp_path / "store")
    assert_names_the_extra(result, "dask")


def test_extras_report_missing_modules(monkeypatch):
    monkeypatch.setitem(sys.modules, "daqp", None)
    assert extras.missing("mpc") == ["daqp"] and extras.is_installed("yaml")
    assert extras.expectation("mpc") == "an installed daqp (pip install 'robofleet[mpc]')"
    with pytest.raises(extras.ConfigError, match=r"^mpc solver: expected an installed daqp \(pip install 'robofleet\[mpc\]'\), received none$"):
        extras.require("mpc", "mpc solver")
