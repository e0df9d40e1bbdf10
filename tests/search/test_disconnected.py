"""A grid whose accessible vertices fall apart (a pocket sealed by an obstacle touching
the border): the assumption report says so, and a robot that starts in the pocket stops
alone instead of ending the others' search (step 8 on a disconnected grid)."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet import load_scenario, simulate
from robofleet.core.errors import ScenarioError
from robofleet.search.guarantees import check
from robofleet.search.simulation import build_problem, run_search_batch

from .helpers import small_spec

# An L-shaped area; the wall from the bottom border to the inner edge seals the corner
# x > 8 (on the hexagonal grid: parts of 39, 2 and 1 accessible vertices).
L_SHAPE = {"family": "search", "situation": 2, "grid": {"kind": "hexagonal", "a": 1.0},
           "workspace": {"bounds": [[0, 0], [10, 0], [10, 4], [4, 4], [4, 10], [0, 10]],
                         "obstacles": [[[7.6, 0.0], [8.0, 0.0], [8.0, 4.0], [7.6, 4.0]]]}}
IN_POCKET = [8.9703, 0.31]


def l_shape(**robots):
    return load_scenario({**L_SHAPE, "robots": robots})


def test_a_robot_in_a_pocket_does_not_end_the_others_search():
    spec = l_shape(starts=[IN_POCKET, [0.31, 0.31], [2.0421, 0.31]])
    for seed in range(3):
        trace = simulate(spec, seed=seed)
        r = trace.results
        assert r["completed"] and r["success"] and r["visited_share"] == 1.0, r
        stops = {e["robot"]: e for e in trace.events if e["kind"] == "stop"}
        assert stops[0]["step"] <= 1 and stops[0]["rule"] == "own", "the trapped robot stops at once"
        assert stops[1]["step"] == stops[2]["step"] == trace.metadata["n_steps"] > 10, "the others search on"


def test_completed_means_every_reachable_vertex_visited_on_a_disconnected_grid():
    spec = l_shape(count=3)
    seeds = list(range(40))
    problems = [build_problem(spec, s) for s in seeds]
    pocket = spec.built_grid().nearest_vertex(np.array([IN_POCKET]))[0][0]
    labels = spec.built_grid().components
    assert sum(bool((labels[p.starts] == labels[pocket]).any()) for p in problems) >= 3, "some starts fall in the pocket"
    for outcome in run_search_batch(problems, "proposed", seeds):
        assert outcome.results["completed"] and outcome.results["visited_share"] == 1.0, outcome.results


def test_the_assumption_report_flags_a_disconnected_grid():
    spec = l_shape(count=3)
    report = spec.assumption_report()
    assert "connected" in [c.name for c in report.failed()] and not report.vertex_complete
    assert "3 parts" in report.guarantee and "pocket" in report.guarantee
    assert report.as_dict()["checks"]["connected"]["evidence"] == "3 part(s) of 39 + 2 + 1 accessible vertices"
    rows = {g.reference: g for g in check(spec)}
    grid_row = rows["Assumptions 2.1, 3.1.3 on the grid"]
    assert not grid_row.holds and "39 + 2 + 1" in grid_row.line()
    assert not rows["Theorem 4.1"].holds and "connected grid" in rows["Theorem 4.1"].detail
    assert rows["Assumption 3.1.3"].holds, "3.1.3 alone cannot see a pocket sealed without a gap"
    fig7 = {g.reference: g for g in check(load_scenario("search/fig7"))}
    assert fig7["Assumptions 2.1, 3.1.3 on the grid"].holds and fig7["Theorem 4.1"].holds


def test_require_guarantee_refuses_a_disconnected_grid():
    with pytest.raises(ScenarioError, match=r"workspace\.obstacles: expected one part .* received '2 part\(s\) of 30 \+ 2"):
        small_spec(**{"grid.kind": "hexagonal"})
