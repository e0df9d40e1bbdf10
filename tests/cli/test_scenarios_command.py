"""``robofleet scenarios``: one line per scenario, or full descriptions with NAME or ``--long``."""

from __future__ import annotations

import pytest

from robofleet.cli.main import main
from robofleet.core import catalogue


def words(text: str) -> list[str]:
    return text.split()


def test_a_name_shows_its_whole_leading_comment(capsys):
    main(["scenarios", "coordination/warehouse_50"])
    out = capsys.readouterr().out
    entry = next(e for e in catalogue.list() if e.name == "coordination/warehouse_50")
    full = catalogue.leading_comment(entry.path.read_text())
    assert len(full) > len(entry.description)  # the one-line listing cuts this one
    assert out.splitlines()[0] == "coordination/warehouse_50 (coordination)"
    assert words(full) == words(out.split("\n", 1)[1].rsplit("file:", 1)[0])
    assert out.strip().endswith(f"file: {entry.path}")


def test_long_shows_every_full_description_of_a_family(capsys):
    main(["scenarios", "--long", "--family", "search"])
    out = capsys.readouterr().out
    entries = [e for e in catalogue.list() if e.family == "search"]
    assert [line.split()[0] for line in out.splitlines() if line and not line.startswith(" ")] == [e.name for e in entries]
    for entry in entries:
        assert " ".join(words(catalogue.leading_comment(entry.path.read_text()))) in " ".join(words(out))


def test_names_of_sweeps_and_several_names(capsys):
    main(["scenarios", "--sweeps", "buavc_noise"])
    assert capsys.readouterr().out.startswith("buavc_noise (sweep)\n")
    main(["scenarios", "avoidance/circle_swap", "search/fig7"])
    heads = [line for line in capsys.readouterr().out.splitlines() if line and not line.startswith(" ")]
    assert heads == ["avoidance/circle_swap (avoidance)", "search/fig7 (search)"]


def test_an_unknown_name_is_one_line(capsys):
    with pytest.raises(SystemExit) as info:
        main(["scenarios", "avoidance/nope"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: avoidance/nope: expected a file or a shipped scenario name")


def test_the_short_listing_is_unchanged(capsys):
    main(["scenarios"])
    rows = capsys.readouterr().out.strip().splitlines()
    assert [row.split()[0] for row in rows] == catalogue.names()
