"""The built wheel, installed into a fresh virtual environment, works from any directory:
the shipped scenarios and sweeps are inside it and addressable by name."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from robofleet.scenarios import catalogue

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.slow


def run(*args, cwd, env=None, timeout=900):
    result = subprocess.run([str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)
    assert result.returncode == 0, f"{args}: {result.stdout[-2000:]}\n{result.stderr[-2000:]}"
    return result.stdout


@pytest.fixture(scope="module")
def wheel_venv(tmp_path_factory):
    """The wheel built from the source tree, installed with its dependencies into a new
    virtual environment (uv, from its cache, as it installs by default: the modules are
    byte-compiled when first imported, :func:`user_environment`)."""
    base = tmp_path_factory.mktemp("wheel")
    uv = (sys.executable, "-m", "uv")
    run(*uv, "build", "--quiet", "--wheel", "--out-dir", base / "dist", ROOT, cwd=base)
    (wheel,) = (base / "dist").glob("robofleet-*.whl")
    venv = base / "venv"
    run(*uv, "venv", "--quiet", "--python", getattr(sys, "_base_executable", sys.executable), venv, cwd=base)
    run(*uv, "pip", "install", "--quiet", "--python", venv / "bin" / "python", wheel, cwd=base)
    return venv


def user_environment() -> dict[str, str]:
    """This environment as a user's shell has it: no source tree on the path, and Python
    writing the bytecode of what it imports (as it does unless told otherwise)."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONDONTWRITEBYTECODE")} | {"MPLBACKEND": "Agg"}


def test_wheel_ships_the_catalogue_and_runs_by_name_from_anywhere(wheel_venv, tmp_path):
    env = user_environment()
    robofleet = wheel_venv / "bin" / "robofleet"
    listing = run(robofleet, "scenarios", cwd=tmp_path, env=env)
    assert "avoidance/circle_swap" in listing and "search/fig7" in listing and "coordination/fig2_three_robots" in listing
    assert "buavc_noise" in run(robofleet, "scenarios", "--sweeps", cwd=tmp_path, env=env)
    run(robofleet, "validate", "coordination/fig2_three_robots", cwd=tmp_path, env=env)
    run(robofleet, "check", "search/fig7", cwd=tmp_path, env=env)
    probe = (
        "import robofleet, robofleet.scenarios as s, robofleet.experiments as e\n"
        "assert 'site-packages' in str(s.path('avoidance/circle_swap'))\n"
        f"assert s.names() == {catalogue.names()!r}\n"
        "plan = e.plan_sweep('buavc_noise')\n"
        "assert plan.tasks\n"
        "t = robofleet.simulate(robofleet.load_scenario('avoidance/circle_swap', {'max_steps': 3}), seed=1)\n"
        "assert t.summary()['family'] == 'avoidance'\n"
        "print(robofleet.__file__)\n"
    )
    where = run(wheel_venv / "bin" / "python", "-c", probe, cwd=tmp_path, env=env)
    assert str(ROOT) not in where


def test_wheel_ships_the_replay_page_and_view_writes_it(wheel_venv, tmp_path):
    """The replay page's template, script and style are package data: `view` works from
    an installed wheel."""
    env = user_environment()
    robofleet = wheel_venv / "bin" / "robofleet"
    run(robofleet, "run", "avoidance/circle_swap", "--seed", "1", "--out", tmp_path / "run", cwd=tmp_path, env=env)
    run(robofleet, "view", tmp_path / "run", "--no-open", "--out", tmp_path / "replay.html", cwd=tmp_path, env=env)
    page = (tmp_path / "replay.html").read_text()
    assert "<canvas" in page and "data-ready" in page  # the template and its script are inside
