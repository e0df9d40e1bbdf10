"""Every declared reproduction, at its smallest budget, gives identical rows on the serial
and process executors and writes the same files as every other reproduction."""

from __future__ import annotations

import pytest

from robofleet.experiments import deterministic_columns, reproduce
from robofleet.experiments.reproductions import REPRODUCTIONS
from robofleet.scenarios import FAMILIES, catalogue


def test_every_family_has_a_reproduction_and_its_sweeps_are_shipped():
    assert {r.family for r in REPRODUCTIONS.values()} == set(FAMILIES)
    shipped = set(catalogue.names("sweeps"))
    for reproduction in REPRODUCTIONS.values():
        assert set(reproduction.sweeps) <= shipped, reproduction.name


@pytest.mark.parametrize("name", sorted(REPRODUCTIONS))
def test_smallest_budget_identical_on_serial_and_process(name, tmp_path):
    declaration = REPRODUCTIONS[name]
    serial = reproduce(declaration, tmp_path / "serial", budget="smallest", executor="serial", progress=False)
    process = reproduce(declaration, tmp_path / "process", budget="smallest", executor="process", workers=2, progress=False)
    assert serial.failed == 0, {k: f["error"].dropna().tolist()[:1] for k, f in serial.frames.items()}
    for sweep in declaration.sweeps:
        a, b = serial.frames[sweep], process.frames[sweep]
        columns = deterministic_columns(a)
        assert len(a) > 0
        assert a[columns].equals(b[columns]), sweep
    for result, out in ((serial, tmp_path / "serial"), (process, tmp_path / "process")):
        assert (out / "summary.csv").is_file() and (out / "table.md").is_file()
        assert all(p.is_dir() and any(p.iterdir()) or p.is_file() and p.stat().st_size for p in result.files)
        assert {p.name for p in (out / "runs").iterdir()} == set(declaration.sweeps)
    assert serial.markdown.strip()
