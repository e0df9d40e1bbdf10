"""``robofleet run --overwrite`` stopped at any moment: the directory holds the earlier run
or the new one, complete, and the one line printed names exactly the files on disk.

Ctrl-C is injected in process at every point where the run writes (the simulation, each
writer, every rename, counted from a run that is not stopped), and sent as a real SIGINT
to a ``robofleet`` process at a few moments (one inside the renames that swap the run in,
where it must wait until the new run is in place)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import matplotlib.figure
import PIL.Image
import pytest
import yaml

from robofleet.cli.main import RUN_FILES, main
from robofleet.core.files import is_temporary
from robofleet.core.trace import Trace, write_npz

TINY = {"family": "avoidance", "name": "tiny", "method": "buavc", "delta": 0.1, "dt": 0.1, "max_steps": 3,
        "goal_tolerance": 0.1, "local_box": 2.0, "workspace": {"bounds": [-3, -3, 3, 3]},
        "robots": {"n": 2, "radius": 0.2, "v_max": 0.4, "sigma": 0.05, "layout": {"kind": "antipodal", "r_min": 1.0, "r_max": 2.0}}}
OLD_SEED, NEW_SEED = 1, 2
FIGURES = ["--plot", "--animate"]


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    path = tmp_path_factory.mktemp("scenario") / "tiny.yaml"
    path.write_text(yaml.safe_dump(TINY))
    return path


@pytest.fixture(scope="module")
def earlier_run(scenario, tmp_path_factory):
    """An earlier run with every file a run writes (trace, summary, plot, animation)."""
    out = tmp_path_factory.mktemp("earlier") / "run"
    main(["run", str(scenario), "--seed", str(OLD_SEED), "--out", str(out), "--quiet", *FIGURES])
    return out


@pytest.fixture(scope="module")
def renames(scenario, earlier_run, tmp_path_factory):
    """How many ``os.replace`` calls a run over the earlier one makes: without the
    figures, and with them."""
    counts = {}
    for label, extra in (("run", []), ("figures", FIGURES)):
        counter = CountedReplace(None)
        out = tmp_path_factory.mktemp("counted") / "run"
        shutil.copytree(earlier_run, out)
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(os, "replace", counter)
            main(["run", str(scenario), "--seed", str(NEW_SEED), "--out", str(out), "--quiet", "--overwrite", *extra])
        counts[label] = counter.calls
    return counts


class CountedReplace:
    """``os.replace`` that counts its calls and raises KeyboardInterrupt at call ``stop``."""

    def __init__(self, stop: int | None, real=os.replace):
        self.stop, self.calls, self.real = stop, 0, real

    def __call__(self, *args, **kwargs):
        self.calls += 1
        if self.calls == self.stop:
            raise KeyboardInterrupt
        return self.real(*args, **kwargs)


def interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def half_written(real, path_argument: int, suffix: str):
    """``real`` writing its file, which is then cut to half its length, and Ctrl-C (the
    state of a writer stopped halfway), for files whose name ends in ``suffix``."""
    def writer(*args, **kwargs):
        result = real(*args, **kwargs)
        path = Path(args[path_argument])
        if not path.name.endswith(suffix):
            return result
        with open(path, "r+b") as handle:
            handle.truncate(path.stat().st_size // 2)
        raise KeyboardInterrupt
    return writer


def half_written_text(name: str):
    real = Path.write_text

    def write_text(self, data, *args, **kwargs):
        real(self, data, *args, **kwargs)
        if name in self.name:
            real(self, data[: len(data) // 2], *args, **kwargs)
            raise KeyboardInterrupt
    return write_text


WRITERS = {  # point → (what to patch, its replacement), figures on
    "simulation": ("robofleet.cli.main.simulate", lambda: interrupt),
    "trace.npz half written": ("robofleet.core.trace.write_npz", lambda: half_written(write_npz, 0, ".npz")),
    "trace.json half written": ("pathlib.Path.write_text", lambda: half_written_text("trace.json")),
    "summary.json half written": ("pathlib.Path.write_text", lambda: half_written_text("summary.json")),
    "plot.png half written": ("matplotlib.figure.Figure.savefig", lambda: half_written(matplotlib.figure.Figure.savefig, 1, ".png")),
    "animation.gif half written": ("PIL.Image.Image.save", lambda: half_written(PIL.Image.Image.save, 1, ".gif")),
}


def run_stopped(scenario, earlier_run, tmp_path, capsys, monkeypatch, target, replacement, extra):
    out = tmp_path / "run"
    shutil.copytree(earlier_run, out)
    old = {p.name: p.read_bytes() for p in out.iterdir()}
    monkeypatch.setattr(target, replacement)
    with pytest.raises(SystemExit) as stop:
        main(["run", str(scenario), "--seed", str(NEW_SEED), "--out", str(out), "--quiet", "--overwrite", *extra])
    monkeypatch.undo()
    assert stop.value.code == 130
    return out, old, capsys.readouterr().err


def assert_one_complete_run(out: Path, old: dict[str, bytes], err: str) -> str:
    """``out`` holds the earlier run unchanged or the new one complete, nothing half
    written, and ``err`` is one line naming exactly the run files on disk; returns which."""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("interrupted; "), err
    line = lines[0]
    present = sorted(p.name for p in out.iterdir())
    assert not any(is_temporary(name) for name in present), present
    if {p: (out / p).read_bytes() for p in present} == old:
        which = "earlier"
        assert "the new run was not written" in line and "earlier run's files, unchanged" in line
    else:
        which = "new"
        assert Trace.load(out).seed == NEW_SEED
        assert json.loads((out / "summary.json").read_text())["seed"] == NEW_SEED
        for figure in {"plot.png", "animation.gif"} & set(present):
            with PIL.Image.open(out / figure) as image:
                image.load()  # complete: a half file fails here
            assert (out / figure).read_bytes() != old.get(figure)
        assert f"holds the new run (seed {NEW_SEED})" in line
    named = line.rsplit(": ", 1)[1].split(" (")[0].split(", ")
    assert sorted(named) == sorted(p for p in present if p in RUN_FILES), (line, present)
    return which


@pytest.mark.parametrize("point", list(WRITERS))
def test_ctrl_c_in_any_writer_leaves_one_complete_run_and_says_which(point, scenario, earlier_run, tmp_path, capsys, monkeypatch):
    target, make = WRITERS[point]
    out, old, err = run_stopped(scenario, earlier_run, tmp_path, capsys, monkeypatch, target, make(), FIGURES)
    which = assert_one_complete_run(out, old, err)
    assert which == ("new" if point.startswith(("plot", "animation")) else "earlier")


def test_ctrl_c_at_every_rename_leaves_one_complete_run_and_says_which(renames, scenario, earlier_run, tmp_path, capsys, monkeypatch):
    seen = []
    for stop in range(1, renames["run"] + 1):
        case = tmp_path / str(stop)
        case.mkdir()
        out, old, err = run_stopped(scenario, earlier_run, case, capsys, monkeypatch, "os.replace", CountedReplace(stop), [])
        seen.append(assert_one_complete_run(out, old, err))
    assert set(seen) == {"earlier"}, seen  # without figures a run is in place only when the last rename is done
    for stop in (renames["figures"] - 1, renames["figures"]):  # the figures' own renames
        case = tmp_path / f"figures-{stop}"
        case.mkdir()
        out, old, err = run_stopped(scenario, earlier_run, case, capsys, monkeypatch, "os.replace", CountedReplace(stop), FIGURES)
        assert assert_one_complete_run(out, old, err) == "new"


def test_ctrl_c_before_anything_is_written_to_a_new_directory_leaves_nothing(scenario, tmp_path, capsys, monkeypatch):
    out = tmp_path / "deep" / "new" / "run"
    monkeypatch.setattr("robofleet.core.trace.write_npz", half_written(write_npz, 0, ".npz"))
    with pytest.raises(SystemExit) as stop:
        main(["run", str(scenario), "--seed", "3", "--out", str(out), "--quiet"])
    assert stop.value.code == 130
    assert capsys.readouterr().err.strip() == f"interrupted; nothing was written ({out} was not created)"
    assert list(tmp_path.iterdir()) == []


# -- real SIGINT to a robofleet process ----------------------------------------------------
CHILD = textwrap.dedent("""
    import os, signal, sys
    import numpy as np
    import matplotlib.figure
    import robofleet.cli.main as cli
    import robofleet.core.files as files
    import robofleet.core.trace as trace

    point, out = sys.argv[1], sys.argv[2]

    def sigint_then(real, when=lambda *a, **k: True):
        def wrapper(*args, **kwargs):
            if when(*args, **kwargs):
                os.kill(os.getpid(), signal.SIGINT)
            return real(*args, **kwargs)
        return wrapper

    if point == "simulation":
        cli.simulate = sigint_then(cli.simulate)
    elif point == "trace.npz":
        trace.write_npz = sigint_then(trace.write_npz)
    elif point == "swap":  # inside the renames that put the new run in place
        files.move_in = sigint_then(files.move_in, lambda stage, directory, replaced: str(directory) == out)
    elif point == "plot.png":
        matplotlib.figure.Figure.savefig = sigint_then(matplotlib.figure.Figure.savefig)
    elif point == "outside":  # the test sends SIGINT while the run simulates
        real = cli.simulate
        def announced(*args, **kwargs):
            print("simulating", file=sys.stderr, flush=True)
            return real(*args, **kwargs)
        cli.simulate = announced
    cli.main(sys.argv[3:])
""")
SIGNALLED = {"simulation": "earlier", "trace.npz": "earlier", "swap": "new", "plot.png": "new"}


@pytest.mark.slow
@pytest.mark.parametrize("point", list(SIGNALLED))
def test_a_real_sigint_leaves_one_complete_run(point, scenario, earlier_run, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(earlier_run, out)
    old = {p.name: p.read_bytes() for p in out.iterdir()}
    args = ["run", str(scenario), "--seed", str(NEW_SEED), "--out", str(out), "--quiet", "--overwrite", "--plot"]
    result = subprocess.run([sys.executable, "-c", CHILD, point, str(out), *args], capture_output=True, text=True, timeout=300)
    assert result.returncode == 130, result.stderr
    assert "Traceback" not in result.stderr
    assert assert_one_complete_run(out, old, result.stderr) == SIGNALLED[point]


@pytest.mark.slow
def test_ctrl_c_sent_from_outside_while_the_run_simulates(earlier_run, tmp_path):
    """Whenever the signal lands (in practice: during the simulation, which is long)."""
    long = {**TINY, "max_steps": 5000, "workspace": {"bounds": [-60, -60, 60, 60]},
            "robots": {**TINY["robots"], "n": 12, "layout": {"kind": "antipodal", "r_min": 40.0, "r_max": 50.0}}}
    scenario = tmp_path / "long.yaml"
    scenario.write_text(yaml.safe_dump(long))
    out = tmp_path / "run"
    shutil.copytree(earlier_run, out)
    old = {p.name: p.read_bytes() for p in out.iterdir()}
    args = ["run", str(scenario), "--seed", str(NEW_SEED), "--out", str(out), "--quiet", "--overwrite"]
    child = subprocess.Popen([sys.executable, "-c", CHILD, "outside", str(out), *args], stderr=subprocess.PIPE, text=True)
    try:
        assert child.stderr.readline().strip() == "simulating"
        child.send_signal(signal.SIGINT)
        err = child.stderr.read()
        assert child.wait(timeout=300) == 130, err
    finally:
        if child.poll() is None:
            child.kill()
    assert assert_one_complete_run(out, old, err) in ("earlier", "new")
