"""Property: scaling what sizes a run (robot counts, step budgets, durations, grid edges)
by any factor gives either a one-line refusal or a scenario whose estimated run fits the
memory budget — and validating it never allocates beyond the budget itself (a grid, a
layout of a billion robots): ``tracemalloc`` measures the peak Python and numpy memory
of loading it. (That the estimate bounds what a run records is checked in
``tests/cli/test_memory_budget.py``.)
"""

from __future__ import annotations

import tracemalloc
import zlib

import pytest
from fuzz_mutations import rotated
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import robofleet
from robofleet.core.budget import MEMORY_BUDGET_VARIABLE, parse_size
from robofleet.core.errors import RobofleetError
from robofleet.scenarios import catalogue, family_of

BUDGET = "128MiB"
SIZE_FIELDS = {
    "avoidance": ("robots.n", "max_steps", "teams.0.n"),
    "coordination": ("robots.count", "simulation.max_steps", "planner.max_steps"),
    "flocking": ("followers.count", "duration", "pattern.n_points"),
    "search": ("robots.count", "max_steps", "grid.a"),
}
FACTORS = (10, 1_000, 10**4, 10**6, 10**9, 10**15)


@pytest.fixture(scope="module", autouse=True)
def small_memory_budget():
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(MEMORY_BUDGET_VARIABLE, BUDGET)
        yield


def current(spec, dotted: str):
    node = spec.model_dump()
    for key in dotted.split("."):
        node = node[int(key)] if isinstance(node, list) else node.get(key)
        if node is None:
            return None
    return node


@pytest.mark.parametrize("name", catalogue.names())
@settings(max_examples=18, derandomize=True, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_scaled_sizes_are_refused_or_fit_the_budget(name, data):
    spec = robofleet.load_scenario(name)
    family = family_of(spec)
    offset = zlib.crc32(name.encode())
    field = data.draw(st.sampled_from(rotated(list(SIZE_FIELDS[family.name]), offset)), label="field")
    factor = data.draw(st.sampled_from(rotated(list(FACTORS), offset)), label="factor")
    value = current(spec, field)
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        value = 8  # a count the scenario leaves to its default (a pattern's size...)
    scaled = value / factor if field == "grid.a" else type(value)(value * factor)
    tracemalloc.start()
    try:
        big = robofleet.load_scenario(name, {field: scaled})
    except RobofleetError as exc:
        assert "\n" not in str(exc), str(exc)
    else:
        assert big.run_size().nbytes <= parse_size(BUDGET), f"{field}={scaled}: {big.run_size().describe()}"
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert peak <= parse_size(BUDGET), f"{field}={scaled}: validation peaked at {peak / 2**20:.0f} MiB"
