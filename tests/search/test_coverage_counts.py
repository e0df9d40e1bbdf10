"""The detected share counted over distinct sets of detecting vertices equals the share of
samples the sparse incidence product detects, for any visited set (randomized)."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet import load_scenario
from robofleet.search.coverage import CoverageProbe


@pytest.mark.parametrize("kind, r_st", [("triangular", 1.31), ("square", 0.9), ("hexagonal", 2.2)])
def test_detected_share_equals_the_incidence_product(kind, r_st):
    grid = load_scenario("search/fig7", overrides={"grid.kind": kind, "require_guarantee": False}).built_grid()
    probe = CoverageProbe(grid, r_st)
    rng = np.random.default_rng(22)
    for _ in range(200):
        visited = rng.random(grid.n_vertices) < rng.random() ** 3
        assert probe.detected_share(visited) == float(((probe.incidence @ visited.astype(float)) > 0).mean())
    assert probe.detected_share(np.zeros(grid.n_vertices, bool)) == 0.0
    assert probe.groups[2].sum() == len(probe.samples)
