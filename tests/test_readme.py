"""The README a newcomer reads in five minutes: short, every snippet and command runs as
written, every command of the CLI named, no development history."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from markdown_blocks import ROOT, code_blocks, commands, run_page

README = ROOT / "README.md"
TEXT = README.read_text(encoding="utf-8")
HISTORY = re.compile(r"\bissue \d+|\bstop \d+\b|\bthis stop\b|previous tree|before this change|\bbefore/after\b|\bbefore →|→ shipped", re.I)


def test_the_readme_is_short():
    assert len(TEXT.splitlines()) <= 200


def test_every_command_is_named():
    for command in ("scenarios", "run", "validate", "check", "view", "sweep", "reproduce"):
        assert f"robofleet {command}" in TEXT, command


def test_it_has_python_and_commands_to_run():
    languages = [lang for lang, _ in code_blocks(TEXT)]
    assert languages.count("python") >= 2 and "sh" in languages
    shown = [argv[0] for lang, body in code_blocks(TEXT) if lang == "sh" for argv in commands(body)]
    assert {"make", "robofleet"} <= set(shown)


def test_no_development_history():
    found = HISTORY.findall(TEXT)
    assert not found, found


def test_the_results_digest_is_at_most_ten_lines():
    digest = TEXT.split("## Results", 1)[1].split("\n## ", 1)[0]
    assert len([line for line in digest.splitlines() if line.strip()]) <= 10


@pytest.mark.slow
def test_every_snippet_and_command_runs_as_written(tmp_path: Path):
    assert run_page(README, tmp_path) >= 5
