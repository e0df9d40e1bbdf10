"""Failure detection and injection (Section 4.2: "failure of rob_i will affect its
neighbours"; the vertex of a robot that stops answering is treated as blocked)."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet import simulate

from .helpers import check_step_invariants, small_spec


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("fail_step", [0, 3, 8])
def test_others_finish_and_never_touch_the_failed_robot(seed, fail_step):
    spec = small_spec(**{"situation": 2, "robots.count": 4, "failures": [{"robot": 1, "step": fail_step}]})
    trace = simulate(spec, seed=seed)
    check_step_invariants(trace, spec)
    verts = trace.arrays["vertex"][:, :, 0]
    failures = [e for e in trace.events if e["kind"] == "failure"]
    assert failures == [] or failures[0]["robot"] == 1
    if not failures:  # the search ended before the failure step
        assert trace.metadata["n_steps"] <= fail_step
        return
    k = failures[0]["step"]
    dead = verts[k, 1]
    assert np.all(verts[k:, 1] == dead), "the failed robot does not move"
    others = np.delete(verts[k:], 1, axis=1)
    assert not np.any(others == dead), "a live robot entered the failed robot's vertex"
    assert trace.results["completed"], "the live robots still reach stop rule (4)"
    assert trace.results["failed_robots"] == 1
    # every accessible vertex except the dead one, reachable without passing it, is visited
    grid = spec.built_grid()
    visited = set(np.unique(verts).tolist())
    missing = [v for v in np.flatnonzero(grid.accessible) if v not in visited and v != dead]
    assert len(missing) <= 1  # at most a vertex shadowed behind the failed robot


def test_failure_is_detected_by_neighbours():
    spec = small_spec(**{"situation": 2, "robots.count": 5, "failures": [{"robot": 0, "step": 2}]})
    detected = 0
    for seed in range(8):
        trace = simulate(spec, seed=seed)
        kinds = [e["kind"] for e in trace.events]
        if "failure" in kinds and trace.metadata["n_steps"] > 10:
            detected += "failure_detected" in kinds
    assert detected > 0


def test_situation1_with_failure_still_finds_all_targets():
    spec = small_spec(**{"robots.count": 3, "failures": [{"robot": 2, "step": 1}]})
    for seed in range(5):
        trace = simulate(spec, seed=seed)
        check_step_invariants(trace, spec)
        assert trace.results["found_targets"] == 4 and trace.results["completed"]


def test_random_failure_injection_is_seeded():
    spec = small_spec(**{"situation": 2, "robots.count": 4, "random_failures": {"count": 2, "within_steps": 6}})
    a, b = simulate(spec, seed=5), simulate(spec, seed=5)
    fails = [e for e in a.events if e["kind"] == "failure"]
    assert fails == [e for e in b.events if e["kind"] == "failure"]
    assert len(fails) == 2 and all(e["step"] < 6 for e in fails)
    check_step_invariants(a, spec)
    assert a.results["completed"]
