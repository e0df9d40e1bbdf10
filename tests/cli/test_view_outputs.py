"""``robofleet view --out/--rerun`` never loses data: it never writes over a run's own data
(trace, summary) nor a reproduction's (tables), never replaces a file robofleet did not
write unless ``--overwrite``, and refuses ``--out F --rerun F``; each refusal is one line,
exit status 2, before anything is written."""

from __future__ import annotations

import os
import subprocess

import pytest

import robofleet
from robofleet.cli.main import main
from robofleet.scenarios import FAMILIES


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory):
    spec = robofleet.load_scenario("search/failure_injection", {FAMILIES["search"].budget: 6})
    return robofleet.simulate(spec, seed=1).save(tmp_path_factory.mktemp("saved") / "run")


@pytest.fixture
def run(saved_run, tmp_path):
    """A run directory with its trace and summary."""
    import shutil

    out = shutil.copytree(saved_run, tmp_path / "run")
    (out / "summary.json").write_text('{"seed": 1}\n')
    return out


@pytest.fixture
def reproduction(tmp_path):
    out = tmp_path / "repro"
    (out / "runs" / "sweep").mkdir(parents=True)
    (out / "summary.csv").write_text("table,n\nt,1\n")
    (out / "table.md").write_text("| a |\n|---|\n| 1 |\n")
    (out / "runs" / "sweep" / "run-1.parquet").write_bytes(b"PAR1 data PAR1")
    return out


def contents(directory):
    return {p: p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


def view(args, capsys):
    try:
        main(["view", *map(str, args), "--no-open"])
    except SystemExit as stop:
        return stop.code, capsys.readouterr().err
    return 0, capsys.readouterr().err


def assert_refused(code, err, *words):
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: ") and "Traceback" not in err, err
    for word in words:
        assert word in err, err


@pytest.mark.parametrize("name", ["trace.json", "trace.npz", "summary.json"])
def test_out_never_writes_over_a_runs_data(run, name, capsys):
    before = contents(run)
    for extra in ([], ["--overwrite"]):
        assert_refused(*view([run, "--out", run / name, *extra], capsys), "--out", name)
        assert contents(run) == before


@pytest.mark.parametrize("name", ["summary.csv", "table.md", "runs/sweep/run-1.parquet"])
def test_out_never_writes_over_a_reproductions_data(reproduction, name, capsys):
    before = contents(reproduction)
    for extra in ([], ["--overwrite"]):
        assert_refused(*view([reproduction, "--out", reproduction / name, *extra], capsys), "--out")
        assert contents(reproduction) == before


def test_rerun_never_writes_over_a_runs_data(run, capsys):
    before = contents(run)
    assert_refused(*view([run, "--rerun", run / "trace.npz", "--overwrite"], capsys), "--rerun")
    assert contents(run) == before


@pytest.mark.parametrize("spelling", ["same", "dotted", "link"])
@pytest.mark.parametrize("suffix", [".rrd", ".html"])
def test_out_and_rerun_naming_one_file_is_refused_and_writes_nothing(run, tmp_path, capsys, spelling, suffix):
    target = tmp_path / f"both{suffix}"
    other = {"same": target, "dotted": tmp_path / "x" / ".." / target.name, "link": tmp_path / f"link{suffix}"}[spelling]
    if spelling == "link":
        os.symlink(target, other)
    before = contents(run)
    assert_refused(*view([run, "--out", target, "--rerun", other], capsys), "--rerun", "--out")
    assert not target.exists() and contents(run) == before


def test_a_file_robofleet_did_not_write_is_replaced_only_with_overwrite(run, tmp_path, capsys):
    mine = tmp_path / "notes.html"
    mine.write_text("my notes")
    assert_refused(*view([run, "--out", mine], capsys), "--out", str(mine), "--overwrite")
    assert mine.read_text() == "my notes"
    (run / "replay.html").write_text("my own replay")  # the default page's name, but not robofleet's page
    assert_refused(*view([run], capsys), "--out", "replay.html")
    assert (run / "replay.html").read_text() == "my own replay"
    recording = tmp_path / "mine.rrd"
    recording.write_bytes(b"RRF2 someone else's recording")
    assert_refused(*view([run, "--out", tmp_path / "page.html", "--rerun", recording], capsys), "--rerun", str(recording))
    assert recording.read_bytes() == b"RRF2 someone else's recording" and not (tmp_path / "page.html").exists()
    code, _ = view([run, "--out", mine, "--overwrite"], capsys)
    assert code == 0 and "replay-data" in mine.read_text()


def test_a_page_robofleet_wrote_is_replaced_without_overwrite(run, reproduction, capsys):
    for target, page in ((run, run / "replay.html"), (reproduction, reproduction / "report.html")):
        assert view([target], capsys)[0] == 0
        first = page.stat().st_mtime_ns, page.stat().st_ino
        assert view([target], capsys)[0] == 0
        assert (page.stat().st_mtime_ns, page.stat().st_ino) != first and "robofleet" in page.read_text()[:300]


def test_overwrite_replaces_a_link_not_the_file_it_points_to(run, tmp_path, capsys):
    link = tmp_path / "page.html"
    os.symlink(run / "trace.json", link)
    before = contents(run)
    assert_refused(*view([run, "--out", link], capsys), "--out")
    assert view([run, "--out", link, "--overwrite"], capsys)[0] == 0
    assert not link.is_symlink() and "replay-data" in link.read_text() and contents(run) == before


def test_the_command_line_refuses_out_equal_to_rerun_in_one_line(run, tmp_path, robofleet_bin):
    target = tmp_path / "x.rrd"
    result = subprocess.run([str(robofleet_bin), "view", str(run), "--no-open", "--out", str(target), "--rerun", str(target)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert result.stderr.startswith("error: --rerun: ") and not target.exists()
