"""The generated reference pages: every scenario field of every family has a unit-bearing
meaning, every documented field exists, every summary key and reproduction is listed, and
the types, defaults and limits shown are the code's (generated, so they cannot drift)."""

from __future__ import annotations

import sys
from pathlib import Path

from pydantic_core import PydanticUndefined

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

import robofleet_reference as reference  # noqa: E402
from robofleet.core.trace import CORE_SUMMARY_KEYS  # noqa: E402
from robofleet.experiments.reproductions import REPRODUCTIONS  # noqa: E402
from robofleet.scenarios import FAMILIES  # noqa: E402


def test_every_field_is_described_and_every_description_is_a_field():
    assert reference.problems() == []


def test_a_field_without_meaning_or_a_stale_meaning_is_reported():
    notes = reference.notes()
    del notes["avoidance"]["Spec"]["delta"]
    notes["search"]["GridSpec"]["gone"] = ["", "a field the code no longer has"]
    found = reference.problems(notes)
    assert any("top level.delta" in p for p in found) and any("GridSpec.gone" in p for p in found)


def test_every_field_appears_with_its_default_and_limits():
    for name, family in FAMILIES.items():
        page = reference.render_family(name)
        for section in reference.sections(family.spec):
            for field, info in section.model.model_fields.items():
                row = next(line for line in page.splitlines() if line.startswith(f"| `{field}` |"))
                assert row, (name, field)
                limits = reference.limits_text(info)
                assert limits in page, (name, field, limits)
                if info.default is PydanticUndefined and info.default_factory is None:
                    assert "**required**" in page


def test_the_units_are_given_where_a_field_has_one():
    page = reference.render_family("avoidance")
    assert "| `v_max` | number | `0.4` | > 0 | m/s |" in page
    assert "| `delta` | number | `0.1` | > 0, < 1 |  |" in page


def test_every_summary_key_and_reproduction_is_listed():
    keys = reference.render_summary_keys()
    for key in CORE_SUMMARY_KEYS:
        assert f"| `{key}` |" in keys
    for family in FAMILIES.values():
        for key in family.results:
            assert f"| `{key}` |" in keys, (family.name, key)
    table = reference.render_reproductions()
    for name in REPRODUCTIONS:
        assert f"| `{name}` |" in table


def test_markers_expand_and_other_lines_stay():
    text = "# T\n\nintro\n\n<!-- scenario-fields: search -->\n\n<!-- summary-keys -->\n"
    out = reference.expand(text)
    assert out.startswith("# T\n\nintro\n") and "<!--" not in out and "`grid`" in out and "## Core keys" in out
