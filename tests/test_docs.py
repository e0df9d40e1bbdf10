"""The documentation site (API reference from the docstrings + guide pages) builds
without a single warning."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_docs_build_without_warnings(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", "-d", str(tmp_path / "doctrees"),
         str(ROOT / "docs"), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=600, env={"MPLBACKEND": "Agg", "PATH": ""},
    )
    assert result.returncode == 0, result.stderr[-5000:]
    assert (tmp_path / "html" / "api" / "generated" / "robofleet.core.recorder.html").is_file() or \
        any((tmp_path / "html").rglob("robofleet.core.recorder*.html"))
    # no page shows an object's memory address (it differs from build to build)
    assert [p.name for p in (tmp_path / "html").rglob("*.html") if " object at 0x" in p.read_text(encoding="utf-8")] == []
