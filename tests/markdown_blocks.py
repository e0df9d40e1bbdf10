"""Run the code blocks of a Markdown page as a reader would: shared by the README and docs tests.

``python`` blocks run in one namespace per page, ``sh`` blocks one command per line (the
``robofleet`` commands through the command line's entry point in this process, ``python``
commands through this interpreter, ``make TARGET`` as a dry run of that target), YAML blocks with a ``family`` key are loaded as scenarios; blocks in
any other language (``text``, none) are illustrations and are not run. Blocks run in page
order in one working directory where the checkout's ``scenarios/``, ``sweeps/`` and
``examples/`` are visible, so a later block may read what an earlier one wrote.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^(?P<fence>```+)(?P<lang>[^\s`{]*)[^\n]*\n(?P<body>.*?)^(?P=fence)[ \t]*$", re.S | re.M)
VISIBLE = ("scenarios", "sweeps", "examples")
RUN_LANGUAGES = ("python", "sh", "yaml")


def code_blocks(text: str) -> list[tuple[str, str]]:
    """``(language, body)`` of every fenced block (MyST directives such as ``{toctree}`` excluded)."""
    return [(m["lang"], m["body"]) for m in FENCE.finditer(text)]


def runnable_blocks(path: Path) -> list[tuple[str, str]]:
    return [(lang, body) for lang, body in code_blocks(path.read_text(encoding="utf-8")) if lang in RUN_LANGUAGES]


def commands(body: str) -> list[list[str]]:
    """The commands of a shell block, one per line, comments dropped."""
    out = []
    for line in body.splitlines():
        argv = shlex.split(line, comments=True)
        if argv:
            out.append(argv)
    return out


def prepare(workdir: Path) -> Path:
    """A working directory that sees the checkout's catalogue and examples."""
    for name in VISIBLE:
        link = workdir / name
        if not link.exists():
            link.symlink_to(ROOT / name, target_is_directory=True)
    return workdir


def run_command(argv: list[str], workdir: Path) -> subprocess.CompletedProcess:
    """One command of a shell block, as a reader would type it (``make`` as a dry run)."""
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    if argv[0] == "make":
        return subprocess.run(["make", "-n", *argv[1:]], cwd=ROOT, capture_output=True, text=True, env=env, timeout=60)
    if argv[0] == "robofleet":
        argv = [sys.executable, "-m", "robofleet", *argv[1:]]
    elif argv[0] == "python":
        argv = [sys.executable, *argv[1:]]
    else:
        raise AssertionError(f"a shell block runs a command the docs test cannot run: {shlex.join(argv)}")
    return subprocess.run(argv, cwd=workdir, capture_output=True, text=True, env=env, timeout=600)


def run_robofleet(argv: list[str]) -> tuple[int, str]:
    """``robofleet ARGS`` as a reader types it, through the command line's entry point in
    this process (the libraries every command loads are loaded once per test process, not
    once per command): its exit status and standard error. An error the command line does
    not turn into its one-line message propagates (a reader would see a traceback)."""
    from robofleet.cli.main import main

    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            main(argv[1:])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    return code, err.getvalue()


def run_shell_command(argv: list[str], workdir: Path) -> tuple[int, str]:
    """One command of a shell block: exit status and standard error."""
    if argv[0] == "robofleet":
        return run_robofleet(argv)
    result = run_command(argv, workdir)
    return result.returncode, result.stderr


def check_ros2_file(data: object, body: str, workdir: Path) -> bool:
    """Read a ROS 2 launch file or a filter's ``ros__parameters`` file as robofleet would;
    whether ``data`` was one."""
    if not isinstance(data, dict):
        return False
    if "nodes" in data:
        from robofleet.ros2.launch import read_launch_file as read
    elif any(isinstance(v, dict) and "ros__parameters" in v for v in data.values()):
        from robofleet.ros2.filter import settings_from_parameters as read
    else:
        return False
    file = workdir / "block.yaml"
    file.write_text(body, encoding="utf-8")
    read(str(file))
    return True


def run_page(path: Path, workdir: Path) -> int:
    """Run every runnable block of ``path`` in order; returns how many ran. Fails on the first error."""
    import robofleet

    prepare(workdir)
    namespace: dict = {}
    ran = 0
    here = Path.cwd()
    os.chdir(workdir)
    try:
        for lang, body in runnable_blocks(path):
            if lang == "python":
                exec(compile(body, f"{path.name}: python block", "exec"), namespace)
            elif lang == "sh":
                for argv in commands(body):
                    code, stderr = run_shell_command(argv, workdir)
                    assert code == 0, f"{path.name}: `{shlex.join(argv)}` exited {code}: {stderr[-2000:]}"
                    assert "Traceback" not in stderr, f"{path.name}: `{shlex.join(argv)}`: {stderr[-2000:]}"
            else:
                data = yaml.safe_load(body)
                if isinstance(data, dict) and "family" in data:
                    robofleet.load_scenario(data)
                elif not check_ros2_file(data, body, workdir):
                    continue
            ran += 1
    finally:
        os.chdir(here)
    return ran
