"""Every file robofleet writes is written whole: into a temporary file next to it, renamed
into place only once complete (:mod:`robofleet.core.files`). Stopped at any moment, a
writer leaves the earlier file (or set of files) as it was, or the new one complete, and
no temporary behind it."""

from __future__ import annotations

import os
import re
import signal
import threading
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

import robofleet
from robofleet.coordination.trajectories import make_trajectories, save_trajectories
from robofleet.core import files
from robofleet.core.files import deferred_interrupts, is_temporary, replacing, staged_files, write_bytes, write_text
from robofleet.core.trace import Trace
from robofleet.experiments.reproduction import write_tables
from robofleet.scenarios import FAMILIES
from robofleet.viz.animation import save_figure, save_gif
from robofleet.viz.replay.page import write_page

SOURCE = Path(robofleet.__file__).parent


def interrupt_at_rename(monkeypatch, stop: int = 1):
    """``os.replace`` raising KeyboardInterrupt at its ``stop``-th call (the others pass)."""
    real, calls = os.replace, []

    def replace(*args, **kwargs):
        calls.append(args)
        if len(calls) == stop:
            raise KeyboardInterrupt
        return real(*args, **kwargs)
    monkeypatch.setattr(os, "replace", replace)
    return calls


def listing(directory: Path) -> dict[str, bytes]:
    return {str(p.relative_to(directory)): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


# -- the helpers ---------------------------------------------------------------------------
def test_replacing_leaves_the_earlier_file_when_stopped_at_any_moment(tmp_path, monkeypatch):
    target = tmp_path / "deep" / "file.txt"
    assert write_text(target, "earlier") == target and target.read_text() == "earlier"
    with pytest.raises(KeyboardInterrupt), replacing(target) as temp:
        assert temp.parent == target.parent and is_temporary(temp) and temp.suffix == ".txt"
        temp.write_text("half")
        raise KeyboardInterrupt
    assert listing(tmp_path) == {"deep/file.txt": b"earlier"}
    interrupt_at_rename(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        write_bytes(target, b"new")
    monkeypatch.undo()
    assert listing(tmp_path) == {"deep/file.txt": b"earlier"}
    write_bytes(target, b"new")
    assert listing(tmp_path) == {"deep/file.txt": b"new"}


def test_staged_files_swap_in_all_or_nothing_at_every_rename(tmp_path, monkeypatch):
    old = {"a.txt": b"old a", "b.txt": b"old b", "gone.txt": b"old, not rewritten", "notes.txt": b"mine"}
    new = {"a.txt": b"new a", "b.txt": b"new b", "c.txt": b"new c"}
    kept = {"notes.txt": b"mine"}

    def swap(directory):
        with staged_files(directory, ["a.txt", "b.txt", "c.txt", "gone.txt"]) as staging:
            for name, data in new.items():
                (staging.path / name).write_bytes(data)
        return staging

    counted = tmp_path / "counted"
    counted.mkdir()
    for name, data in old.items():
        (counted / name).write_bytes(data)
    calls = interrupt_at_rename(monkeypatch, stop=0)
    swap(counted)
    monkeypatch.undo()
    assert listing(counted) == {**new, **kept}
    for stop in range(1, len(calls) + 1):
        directory = tmp_path / str(stop)
        directory.mkdir()
        for name, data in old.items():
            (directory / name).write_bytes(data)
        interrupt_at_rename(monkeypatch, stop)
        with pytest.raises(KeyboardInterrupt):
            swap(directory)
        monkeypatch.undo()
        assert listing(directory) == old, stop


def test_staged_files_remove_the_folders_they_made_when_stopped(tmp_path):
    with pytest.raises(KeyboardInterrupt), staged_files(tmp_path / "a" / "b") as staging:
        (staging.path / "x").write_text("half")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_a_real_ctrl_c_during_the_swap_waits_until_the_new_files_are_in(tmp_path, monkeypatch):
    (tmp_path / "a.txt").write_text("old")
    real = files.move_in

    def signalled(stage, directory, replaced):
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C in the middle of the renames
        return real(stage, directory, replaced)
    monkeypatch.setattr(files, "move_in", signalled)
    with pytest.raises(KeyboardInterrupt):
        with staged_files(tmp_path, ["a.txt"]) as staging:
            (staging.path / "a.txt").write_text("new")
    assert staging.moved and listing(tmp_path) == {"a.txt": b"new"}


def test_deferred_interrupts_deliver_ctrl_c_after_the_block_and_only_in_the_main_thread():
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with deferred_interrupts():
            os.kill(os.getpid(), signal.SIGINT)
            reached.append("end of block")
    assert reached == ["end of block"] and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    errors = []

    def in_thread():
        try:
            with deferred_interrupts():
                reached.append("thread")
        except BaseException as exc:  # pragma: no cover - the failure this test looks for
            errors.append(exc)
    worker = threading.Thread(target=in_thread)
    worker.start()
    worker.join()
    assert errors == [] and reached[-1] == "thread"


# -- every writer --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def two_traces():
    spec = robofleet.load_scenario("search/failure_injection", {FAMILIES["search"].budget: 4})
    return robofleet.simulate(spec, seed=1), robofleet.simulate(spec, seed=2)


def figure(label: str):
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.set_title(label)
    return fig


def gif(label: str, path: Path):
    fig = figure(label)
    return save_gif(fig, lambda k: fig.axes[0].set_xlabel(f"{label} {k}"), range(2), path, progress=False)


def trajectories(offset: float):
    paths = [np.array([[0.0, 0.0], [1.0, offset]]), np.array([[5.0, 5.0], [5.0, 6.0 + offset]])]
    return make_trajectories(paths, radius=0.1, dt=0.1)


WRITERS = {  # name → writer(version, directory): writes version 0 or 1 of its file(s) into directory
    "trace": lambda v, d, traces: traces[v].save(d / "run"),
    "figure": lambda v, d, traces: save_figure(figure(f"version {v}"), d / "plot.png"),
    "gif": lambda v, d, traces: gif(f"version {v}", d / "animation.gif"),
    "page": lambda v, d, traces: write_page(f"<html>version {v}</html>", d / "replay.html"),
    "tables": lambda v, d, traces: write_tables({"t": pd.DataFrame({"v": [v]})}, f"version {v}", d),
    "plan npz": lambda v, d, traces: save_trajectories(trajectories(v), d / "plan.npz"),
    "plan csv": lambda v, d, traces: save_trajectories(trajectories(v), d / "plan.csv"),
    "store": lambda v, d, traces: robofleet.experiments.ResultStore(d).write_rows({"run_id": "a", "seed": 0}, [{"v": v}]),
}


@pytest.mark.parametrize("name", list(WRITERS))
def test_every_writer_stopped_at_any_rename_leaves_the_earlier_files(name, two_traces, tmp_path, monkeypatch):
    write = WRITERS[name]
    reference = tmp_path / "reference"
    reference.mkdir()
    write(0, reference, two_traces)
    earlier = listing(reference)
    calls = interrupt_at_rename(monkeypatch, stop=0)
    write(1, reference, two_traces)
    monkeypatch.undo()
    renamed = len(calls)
    assert renamed >= 1 and listing(reference) != earlier
    for stop in range(1, renamed + 1):
        directory = tmp_path / str(stop)
        directory.mkdir()
        write(0, directory, two_traces)
        interrupt_at_rename(monkeypatch, stop)
        with pytest.raises(KeyboardInterrupt):
            write(1, directory, two_traces)
        monkeypatch.undo()
        after = listing(directory)
        assert not any(is_temporary(Path(p).name) or ".staged" in p for p in after), after
        assert after == earlier, (stop, sorted(after))


WRITER_CALL = re.compile(r"\.write_text\(|\.write_bytes\(|\bsavefig\(|np\.savez\w*\(|\bsavetxt\(|\.to_csv\(|\bwrite_table\(|"
                         r"\bimages\[0\]\.save\(|\brec\.save\(|\bjson\.dump\(|\bopen\([^)]*['\"][wax]b?\+?['\"]")


ALLOWED = ("LOCK_NAME",  # the store's lock file holds the writer's pid, rewritten under the lock: no data
           "archive.open(")  # a member of a zip archive being written (trace.npz, itself written into a staging directory)


def test_every_raw_write_in_the_package_goes_to_a_temporary_or_a_staging_directory():
    """A convention the helpers rely on: the writers that can leave half a file write only
    to the path :func:`replacing` yields (``temp``) or into a staging directory
    (``staging.path``); everything else calls a writer built on them."""
    offending = []
    for path in sorted(SOURCE.rglob("*.py")):
        if path.name == "files.py" and path.parent.name == "core":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if WRITER_CALL.search(line) and not any(word in line for word in ("temp", "staging.path", *ALLOWED)):
                offending.append(f"{path.relative_to(SOURCE)}:{number}: {line.strip()}")
    assert offending == []
