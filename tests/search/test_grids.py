"""Grid geometry (Section 3, Fig. 1): neighbour counts, edge lengths, clearance, step-4 order."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from robofleet.core.errors import ConfigError
from robofleet.core.workspace import Workspace
from robofleet.search.grids import DEGREE, GridKind, build_grid, choice_priority

from .helpers import SMALL_AREA


def area():
    return Workspace.rectangle(*SMALL_AREA["rectangle"], obstacles=[np.asarray(o) for o in SMALL_AREA["obstacles"]])


@pytest.mark.parametrize("kind", list(GridKind))
def test_interior_degree_and_edge_length(kind):
    grid = build_grid(Workspace.rectangle(0, 0, 12, 10), kind, 1.0, 0.31)
    deg = (grid.neighbours >= 0).sum(axis=1)
    clear = grid.workspace.boundary_distance(grid.points) > 1.0 + 1e-6
    assert clear.sum() > 10
    assert np.all(deg[clear] == DEGREE[kind])
    src, slot = np.nonzero(grid.neighbours >= 0)
    lengths = np.linalg.norm(grid.points[grid.neighbours[src, slot]] - grid.points[src], axis=1)
    np.testing.assert_allclose(lengths, 1.0, atol=1e-9)
    # no two vertices closer than a (the lattice is regular)
    d = np.linalg.norm(grid.points[:, None] - grid.points[None], axis=-1) + np.eye(grid.n_vertices) * 9
    assert d.min() >= 1.0 - 1e-9


@pytest.mark.parametrize("kind", list(GridKind))
def test_neighbour_table_is_symmetric(kind):
    grid = build_grid(area(), kind, 0.8, 0.31)
    for v, row in enumerate(grid.neighbours):
        for w in row[row >= 0]:
            assert v in grid.neighbours[w]


@settings(max_examples=25, deadline=None)
@given(kind=st.sampled_from(list(GridKind)), a=st.floats(0.5, 1.5), r_safe=st.floats(0.05, 0.5))
def test_accessibility_matches_brute_force_clearance(kind, a, r_safe):
    ws = area()
    grid = build_grid(ws, kind, a, r_safe)
    free = ws.free_polygon
    outside = shapely.box(-50, -50, 60, 60).difference(ws.boundary_polygon)
    solid = shapely.union_all([outside, *ws.obstacle_polygons])
    clearance = shapely.distance(shapely.points(grid.points), solid)
    np.testing.assert_array_equal(grid.accessible, clearance >= r_safe - 1e-9)
    assert shapely.contains_xy(ws.boundary_polygon.buffer(1e-9), grid.points[:, 0], grid.points[:, 1]).all()
    # edges: free exactly when the segment keeps r_safe clearance (and both ends accessible)
    src, slot = np.nonzero(grid.neighbours >= 0)
    dst = grid.neighbours[src, slot]
    seg = shapely.linestrings(np.stack([grid.points[src], grid.points[dst]], axis=1))
    ok = (shapely.distance(seg, solid) >= r_safe - 1e-9) & grid.accessible[src] & grid.accessible[dst]
    np.testing.assert_array_equal(grid.edge_ok[src, slot], ok)
    assert free.area > 0


def test_block_distance_within_a_plus_r_safe():
    """A blocked edge is blocked by a point within a + r_safe of its start (why Assumption 2.4 suffices)."""
    grid = build_grid(area(), GridKind.TRIANGULAR, 1.0, 0.31)
    blocked = (grid.neighbours >= 0) & ~grid.edge_ok & grid.accessible[:, None]
    assert blocked.any()
    assert np.all(grid.block_distance[blocked] <= 1.0 + 0.31 + 1e-9)
    assert np.all(np.isinf(grid.block_distance[grid.edge_ok]))


def test_choice_priority_matches_paper_definition():
    """Step 4: j before i iff p_jx > p_ix or (p_jy > p_iy and p_jx >= p_ix) — brute force."""
    grid = build_grid(area(), GridKind.TRIANGULAR, 1.0, 0.31)
    rank = choice_priority(grid.points)
    p = grid.points
    for i in range(0, grid.n_vertices, 3):
        for j in range(grid.n_vertices):
            if i == j:
                continue
            xj, xi = round(p[j, 0], 9), round(p[i, 0], 9)
            first = xj > xi or (p[j, 1] > p[i, 1] and xj >= xi)
            assert (rank[j] > rank[i]) == first


@pytest.mark.parametrize("a", [0.0, -1.0, float("nan")])
def test_bad_edge_length(a):
    with pytest.raises(ConfigError, match="a: expected a positive edge length"):
        build_grid(area(), GridKind.TRIANGULAR, a, 0.31)


def test_border_vertices_are_accessible_and_near_border():
    grid = build_grid(area(), GridKind.TRIANGULAR, 1.0, 0.31)
    border = grid.border_vertices()
    assert len(border) > 10
    assert grid.accessible[border].all()
    assert np.all(grid.workspace.boundary_distance(grid.points[border]) < 1.31)
