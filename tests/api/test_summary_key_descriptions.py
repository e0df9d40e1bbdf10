"""Summary keys that count what a heuristic detected say so in their description (the
summary-keys reference page is generated from these descriptions)."""

from __future__ import annotations

import pytest

from robofleet.scenarios import FAMILIES

HEURISTIC_COUNTS = {"avoidance": ("deadlock_detections", "livelock_detections")}
"""The summary keys whose value counts firings of a detection heuristic, per family."""


def detection_keys(results: dict[str, str]) -> list[str]:
    return [key for key in results if "detection" in key]


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_every_detection_count_is_declared_heuristic_and_says_so(family):
    results = FAMILIES[family].results
    assert set(detection_keys(results)) <= set(HEURISTIC_COUNTS.get(family, ()))
    for key in HEURISTIC_COUNTS.get(family, ()):
        assert results[key].startswith("heuristic count: "), (key, results[key])


def test_deadlock_detections_are_not_read_as_deadlocks():
    text = FAMILIES["avoidance"].results["deadlock_detections"]
    assert "no proof of a deadlock" in text and "a run that succeeds may count many" in text
