"""The README documents what the code offers: every family's summary keys, every
command and every reproduction."""

from __future__ import annotations

from pathlib import Path

from robofleet.core.trace import CORE_SUMMARY_KEYS
from robofleet.experiments.reproductions import REPRODUCTIONS
from robofleet.scenarios import FAMILIES

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


def test_every_summary_key_is_documented():
    for key in CORE_SUMMARY_KEYS:
        assert f"| `{key}` |" in README, key
    for family in FAMILIES.values():
        for key, meaning in family.results.items():
            assert f"| `{key}` | {meaning.replace('|', chr(92) + '|')} |" in README, (family.name, key)


def test_every_command_and_reproduction_is_named():
    for command in ("scenarios", "run", "validate", "check", "sweep", "reproduce"):
        assert f"robofleet {command}" in README, command
    for name in REPRODUCTIONS:
        assert f"`{name}`" in README, name
