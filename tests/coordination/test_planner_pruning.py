"""The planner's shortcuts give the answers of the plain computations they replace: the
windowed move check equals comparing every sample with every higher-priority robot, and
the endpoint masks equal the per-robot minima (so plans stay identical)."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.coordination.planner import (
    PRUNE_WINDOW, _clear_of, _move_clear, clear_of_later_starts, clear_of_other_endpoints, window_boxes,
)


def plain_move_clear(higher, reach2, a, b, t0, d):
    pts = a + (b - a) * (np.arange(1, d + 1)[:, None] / d)
    rows = np.minimum(np.arange(t0 + 1, t0 + d + 1), len(higher) - 1)
    return bool(np.all(((higher[rows] - pts[:, None]) ** 2).sum(-1) >= reach2))


@pytest.mark.parametrize("seed", range(6))
def test_windowed_move_check_equals_every_sample(seed):
    """Random walks of higher-priority robots and random moves, many of them grazing at
    exactly ``2r`` (the boundary the margin protects)."""
    rng = np.random.default_rng(seed)
    t, m, reach = int(rng.integers(1, 120)), int(rng.integers(1, 12)), 30.0
    higher = np.cumsum(rng.normal(0, 8, (t, m, 2)), axis=0) + rng.uniform(0, 200, (1, m, 2))
    boxes = window_boxes(higher, PRUNE_WINDOW)
    answers = []
    for _ in range(400):
        a = rng.uniform(-50, 250, 2)
        if rng.random() < 0.5:  # a move ending exactly 2r from a robot's position at that step
            j, row = int(rng.integers(m)), int(rng.integers(t))
            angle = rng.uniform(0, 2 * np.pi)
            b = higher[row, j] + reach * np.array([np.cos(angle), np.sin(angle)])
            d = int(rng.integers(1, 25))
            t0 = max(row - d, -1)  # the planner checks moves from step -1 (its start) on
        else:
            b, d, t0 = rng.uniform(-50, 250, 2), int(rng.integers(1, 25)), int(rng.integers(-1, t + 10))
        got = _move_clear(higher, boxes, PRUNE_WINDOW, reach * reach, a[0], a[1], b[0], b[1], t0, d)
        assert got == plain_move_clear(higher, reach * reach, a, b, t0, d)
        answers.append(got)
    assert 0 < sum(answers) < len(answers)


@pytest.mark.parametrize("seed", range(4))
def test_endpoint_masks_equal_the_per_robot_minima(seed):
    rng = np.random.default_rng(seed)
    n, edges, reach = 7, 40, 30.0
    distances = rng.choice([10.0, 29.999, 30.0, 30.001, 60.0], size=(2 * n, edges), p=[0.02, 0.02, 0.2, 0.2, 0.56])
    others, later = clear_of_other_endpoints(distances, n, reach), clear_of_later_starts(distances, n, reach)
    for i in range(n):
        assert np.array_equal(others[i], _clear_of(np.delete(distances, [i, n + i], axis=0), edges, reach))
        assert np.array_equal(later[i], _clear_of(distances[i + 1:n], edges, reach))
    assert 0 < others.sum() < others.size and 0 < later.sum() < later.size
