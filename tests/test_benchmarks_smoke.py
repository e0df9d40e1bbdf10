"""Every benchmark script still imports and parses its arguments (no timing here).

Each script runs as ``python benchmarks/SCRIPT --help`` would run it (as ``__main__``, its
folder first on the import path, ``--help`` as its argument), in this process: the
libraries the scripts share are imported once, not once per script."""

import runpy
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
SCRIPTS = sorted(BENCHMARKS.glob("*.py"))


@pytest.fixture
def forget_benchmark_modules():
    """Drop the benchmarks' own modules (``_machine``, ...) a script imported, so every
    script imports its helpers afresh, from its folder."""
    yield
    for name, module in list(sys.modules.items()):
        if Path(getattr(module, "__file__", None) or "/").parent == BENCHMARKS:
            del sys.modules[name]


@pytest.mark.parametrize("script", SCRIPTS, ids=[s.stem for s in SCRIPTS])
def test_benchmark_script_starts(script, monkeypatch, capsys, forget_benchmark_modules):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(sys, "argv", [str(script), "--help"])
    with pytest.raises(SystemExit) as exit:
        runpy.run_path(str(script), run_name="__main__")
    out, err = capsys.readouterr()
    assert exit.value.code in (0, None), err[-2000:]
    assert "usage" in out.lower()
