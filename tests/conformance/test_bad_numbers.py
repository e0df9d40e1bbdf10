"""Every number of every shipped scenario, replaced by NaN, ±inf or a huge value, is
refused with a one-line ScenarioError naming the file and the field — never accepted,
never a crash deep inside numpy or GEOS."""

from __future__ import annotations

import copy
import math
import shutil

import pytest
import yaml

import robofleet
from robofleet.core.errors import ScenarioError
from robofleet.scenarios import catalogue

BAD = (math.nan, math.inf, -math.inf, 1e308)


def float_leaves(node, path=()):
    """Paths of the numbers of a YAML mapping (lists indexed; booleans are not numbers)."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield from float_leaves(value, (*path, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from float_leaves(value, (*path, index))
    elif isinstance(node, (int, float)) and not isinstance(node, bool):
        yield path


def replaced(mapping, path, value):
    out = copy.deepcopy(mapping)
    node = out
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return out


@pytest.mark.parametrize("name", catalogue.names())
def test_every_number_made_unreasonable_is_refused_in_one_line(name, tmp_path):
    source = catalogue.path(name)
    shutil.copytree(source.parent, tmp_path / "folder")  # files the scenario names lie beside it
    target = tmp_path / "folder" / source.name
    mapping = yaml.safe_load(source.read_text())
    robofleet.load_scenario(target)  # the copy itself is valid
    for index, leaf in enumerate(float_leaves(mapping)):
        bad = BAD[index % len(BAD)]
        target.write_text(yaml.safe_dump(replaced(mapping, leaf, bad)))
        with pytest.raises(ScenarioError) as info:
            robofleet.load_scenario(target)
        message = str(info.value)
        assert message.startswith(f"{target}: ") and "\n" not in message, (leaf, message)
        assert str(leaf[-1]) in message or any(str(k) in message for k in leaf if isinstance(k, str)), (leaf, message)


def test_the_mutations_reach_every_family():
    counts = {}
    for entry in catalogue.list():
        counts[entry.family] = counts.get(entry.family, 0) + len(list(float_leaves(yaml.safe_load(entry.path.read_text()))))
    assert all(n >= 5 for n in counts.values()), counts
