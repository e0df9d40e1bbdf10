"""Short runs of every family (and of a 3-D avoidance run) shared by the replay tests, and
a headless Chromium for the browser tests (skipped, with the reason, when it is missing)."""

from __future__ import annotations

import importlib.util

import pytest

import robofleet
from robofleet.core.trace import Trace
from robofleet.scenarios import FAMILIES
from robofleet.viz.replay.browser import find_chromium

RUNS = {  # name: (scenario, budget): every family, and the 3-D case of avoidance
    "avoidance": ("avoidance/circle_swap", 120),
    "avoidance_3d": ("avoidance/quadrotors_3d", 12),
    "coordination": ("coordination/x_corridor_20", 3000),
    "flocking": ("flocking/wedge_async", 200),
    "search": ("search/failure_injection", 60),
}


def short_run(scenario: str, budget: int, seed: int = 2) -> Trace:
    family = scenario.split("/")[0]
    return robofleet.simulate(robofleet.load_scenario(scenario, {FAMILIES[family].budget: budget}), seed=seed)


@pytest.fixture(scope="session")
def traces() -> dict[str, Trace]:
    return {name: short_run(scenario, budget) for name, (scenario, budget) in RUNS.items()}


def browser_missing() -> str | None:
    """Why the browser tests cannot run here, or ``None``."""
    if importlib.util.find_spec("websocket") is None:
        return "websocket-client is not installed (pip install 'robofleet[test]')"
    if find_chromium() is None:
        return "no Chromium on PATH (apt-get install chromium): the replay pages are not checked in a browser"
    return None


@pytest.fixture(scope="session")
def browser():
    reason = browser_missing()
    if reason:
        pytest.skip(reason)
    from robofleet.viz.replay.browser import HeadlessChromium

    with HeadlessChromium(width=1280, height=800) as chromium:
        yield chromium
