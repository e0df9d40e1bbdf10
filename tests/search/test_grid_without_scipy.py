"""A search grid is built and checked with numpy alone: its neighbour table is the one of
scipy's k-d tree, its component labels are scipy's connected components, numbering
included."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from robofleet.core.workspace import Workspace
from robofleet.search.grids import DEGREE, GridKind, build_grid, component_labels, neighbour_table


def scipy_components(n: int, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    return connected_components(coo_matrix((np.ones(len(src)), (src, dst)), shape=(n, n)), directed=False)[1]


def k_d_tree_neighbour_table(points: np.ndarray, a: float, degree: int) -> np.ndarray:
    """The neighbour table from the k-d tree's pairs, ordered by angle as the grid orders it."""
    pairs = cKDTree(points).query_pairs(a * (1 + 1e-6), output_type="ndarray").reshape(-1, 2)
    src, dst = np.concatenate([pairs[:, 0], pairs[:, 1]]), np.concatenate([pairs[:, 1], pairs[:, 0]])
    d = points[dst] - points[src]
    order = np.lexsort((np.arctan2(d[:, 1], d[:, 0]), src))
    src, dst = src[order], dst[order]
    table = np.full((len(points), degree), -1, dtype=np.intp)
    table[src, np.arange(len(src)) - np.searchsorted(src, src)] = dst
    return table


def test_component_labels_are_scipys_on_random_graphs_paths_and_isolated_vertices():
    rng = np.random.default_rng(7)
    for _ in range(400):
        n = int(rng.integers(1, 300))
        m = int(rng.integers(0, 2 * n))
        src, dst = rng.integers(0, n, m), rng.integers(0, n, m)
        got = component_labels(n, src, dst)
        assert got.dtype == np.int32 and np.array_equal(got, scipy_components(n, src, dst))
    order = rng.permutation(5000)  # one long path in shuffled vertex order
    assert np.array_equal(component_labels(5000, order[:-1], order[1:]), np.zeros(5000, np.int32))


@pytest.mark.parametrize("kind", list(GridKind))
def test_grids_get_the_k_d_trees_neighbour_table_and_scipys_components(kind):
    rng = np.random.default_rng(list(GridKind).index(kind))
    for _ in range(6):
        w, h, a = rng.uniform(3, 12), rng.uniform(3, 12), rng.uniform(0.3, 1.0)
        x0, y0 = rng.uniform(-100, 100, 2)
        obstacle = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) * rng.uniform(0.5, 2) + [x0 + w / 3, y0 + h / 3]
        workspace = Workspace.rectangle(x0, y0, x0 + w, y0 + h, obstacles=[obstacle])
        grid = build_grid(workspace, kind, a, rng.uniform(0, 0.3))
        assert np.array_equal(grid.neighbours, k_d_tree_neighbour_table(grid.points, a, DEGREE[kind]))
        assert np.array_equal(neighbour_table(grid.points, a, DEGREE[kind]), grid.neighbours)
        src, slot = np.nonzero(grid.edge_ok)
        assert np.array_equal(grid.components, scipy_components(grid.n_vertices, src, grid.neighbours[src, slot]))
