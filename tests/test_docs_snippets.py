"""Every snippet and command of the guide pages runs as written (the results pages state
commands inline, with the time they take; tests/test_references.py checks those)."""

from __future__ import annotations

from pathlib import Path

import pytest

from markdown_blocks import ROOT, runnable_blocks, run_page

DOCS = ROOT / "docs"
GUIDE = sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts and p.parent.name != "results")
WITH_CODE = [p for p in GUIDE if runnable_blocks(p)]


def test_the_guide_pages_have_code_to_run():
    names = {p.relative_to(DOCS).as_posix() for p in WITH_CODE}
    assert {"getting-started.md", "sweeps.md", "reproductions.md", "embedding.md", "scenarios/index.md", "fifth-family.md"} <= names


@pytest.mark.slow
@pytest.mark.parametrize("page", WITH_CODE, ids=lambda p: p.relative_to(DOCS).as_posix())
def test_every_block_runs_as_written(page: Path, tmp_path: Path):
    assert run_page(page, tmp_path) > 0
