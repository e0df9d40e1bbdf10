"""The ``halves`` layout: robots fill the two halves of a box and swap.

Robots stand on a square grid of pitch ``s`` in the box ``[x_0, x_1] × [y_0, y_1]``:
rows at ``y = y_0 + s/2 + j s`` (``j < ⌊(y_1 − y_0)/s⌋``), columns from each outer edge
inward, ``x = x_0 + s/2 + c s`` on the left and its mirror ``x_0 + x_1 − x`` on the right.
Robot ``2k`` takes the ``k``-th left spot (column by column, row by row) and robot
``2k + 1`` its mirror image; every robot's goal is the mirror image of its start, so the
two crowds cross the middle head-on, row against row. With ``n`` robots the outer
``⌈n / (2 rows)⌉`` columns of each half fill first; a half holds ``rows · ⌊(x_1 − x_0)/(2 s)⌋``.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import ScenarioError


def halves_points(n: int, box, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals ``(n, 2)`` of the ``halves`` layout (module docstring)."""
    x0, y0, x1, y1 = map(float, box)
    rows, columns = int(np.floor((y1 - y0) / spacing + 1e-9)), int(np.floor((x1 - x0) / (2 * spacing) + 1e-9))
    left = (n + 1) // 2
    if left > rows * columns:
        raise ScenarioError("layout.box", f"room for {n} robots at spacing {spacing} (each half holds {rows * columns})", list(box))
    k = np.arange(left)
    spots = np.column_stack([x0 + spacing / 2 + (k // rows) * spacing, y0 + spacing / 2 + (k % rows) * spacing])
    mirror = spots * [-1.0, 1.0] + [x0 + x1, 0.0]
    starts = np.empty((2 * left, 2))
    starts[0::2], starts[1::2] = spots, mirror
    goals = starts * [-1.0, 1.0] + [x0 + x1, 0.0]
    return starts[:n], goals[:n]


def longest_halves_trip(box, spacing: float) -> float:
    """The longest start–goal distance of a ``halves`` layout: the outermost columns [m]."""
    return float(box[2] - box[0] - spacing)
