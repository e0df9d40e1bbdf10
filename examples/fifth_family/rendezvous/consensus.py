"""The algorithm: one step of range-limited consensus, pure and vectorized.

Robot i moves to ``x_i + g/(1 + d_i) · Σ_{j ∈ N_i} (x_j − x_i)``, where ``N_i`` are the
robots within the sensing range and ``d_i = |N_i|``. The new position is the convex
combination ``(1 − g d_i/(1 + d_i)) x_i + g/(1 + d_i) Σ_j x_j`` (all weights ≥ 0 for
``0 < g ≤ 1``), so it lies in the convex hull of the robot and its neighbours: the hull
of the whole fleet never grows.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def neighbour_pairs(positions: np.ndarray, sensing_range: float) -> np.ndarray:
    """``(P, 2)`` index pairs ``i < j`` of robots within ``sensing_range`` (a k-d tree, O(N log N + P))."""
    return cKDTree(positions).query_pairs(sensing_range, output_type="ndarray")


def consensus_step(positions: np.ndarray, sensing_range: float, gain: float) -> np.ndarray:
    """The positions ``(N, 2)`` after one step (module docstring)."""
    pairs = neighbour_pairs(positions, sensing_range)
    pull = np.zeros_like(positions)
    degree = np.zeros(len(positions))
    if len(pairs):
        offset = positions[pairs[:, 1]] - positions[pairs[:, 0]]
        np.add.at(pull, pairs[:, 0], offset)
        np.add.at(pull, pairs[:, 1], -offset)
        np.add.at(degree, pairs.ravel(), 1.0)
    return positions + gain / (1.0 + degree)[:, None] * pull


def components(positions: np.ndarray, sensing_range: float) -> int:
    """Connected components of the sensing graph (union-find over the pairs)."""
    parent = np.arange(len(positions))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in neighbour_pairs(positions, sensing_range):
        parent[root(i)] = root(j)
    return len({root(i) for i in range(len(positions))})
