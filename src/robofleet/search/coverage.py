"""Detected share of the area (Section 3, "complete search").

A point of ``A_d = A \\ O`` (Definition 2.1) is *detected* when it lies within ``r_st`` of a
visited vertex. :class:`CoverageProbe` samples ``A_d`` on a fine square lattice once per
grid and keeps, for every sample, the vertices that see it (a sparse incidence matrix), so
the detected share of a run is one sparse matrix–vector product.
"""

from __future__ import annotations

import numba
import numpy as np
import shapely
from scipy import sparse
from scipy.spatial import cKDTree

from .grids import EPS, Grid


class CoverageProbe:
    """Samples of ``A_d`` and which vertices detect them.

    Parameters
    ----------
    grid:
        the grid (its workspace defines ``A`` and ``O``).
    r_st:
        target sensing range.
    spacing:
        sample spacing; the share is an area share up to O(spacing) at the border.
    """

    def __init__(self, grid: Grid, r_st: float, spacing: float | None = None):
        spacing = spacing if spacing is not None else grid.a / 12
        xmin, ymin, xmax, ymax = grid.workspace.extent
        xs = np.arange(xmin + spacing / 2, xmax, spacing)
        ys = np.arange(ymin + spacing / 2, ymax, spacing)
        gx, gy = np.meshgrid(xs, ys)
        pts = np.column_stack([gx.ravel(), gy.ravel()])
        free = grid.workspace.free_polygon
        self.samples = pts[shapely.contains_xy(free, pts[:, 0], pts[:, 1])]
        pairs = cKDTree(self.samples).query_ball_point(grid.points, r_st + EPS)
        cols = np.concatenate([np.full(len(p), v) for v, p in enumerate(pairs)]) if len(pairs) else np.empty(0)
        rows = np.concatenate([np.asarray(p, dtype=np.intp) for p in pairs]) if len(pairs) else np.empty(0)
        self.incidence = sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(self.samples), grid.n_vertices))
        self.groups = distinct_rows(self.incidence)

    def detected(self, visited: np.ndarray) -> np.ndarray:
        """Boolean mask over the samples: detected from some visited vertex."""
        return (self.incidence @ np.asarray(visited, dtype=float)) > 0

    def detected_share(self, visited: np.ndarray) -> float:
        """Share of ``A_d`` detected from the ``visited (V,)`` vertices: the samples whose
        set of detecting vertices holds a visited one, counted once per distinct set
        (:attr:`groups`) in one compiled pass."""
        if not len(self.samples):
            return 1.0
        return detected_count(*self.groups, np.asarray(visited, dtype=bool)) / len(self.samples)

    def undetected(self, visited: np.ndarray) -> np.ndarray:
        """Sample points ``(m, 2)`` not detected from any visited vertex."""
        return self.samples[~self.detected(visited)]


def distinct_rows(incidence: sparse.csr_matrix) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct rows of a CSR incidence as ``(indptr, indices, count)``: each distinct set
    of column indices once, with the number of rows holding it."""
    counts: dict[bytes, int] = {}
    sets: dict[bytes, np.ndarray] = {}
    indptr, indices = incidence.indptr, incidence.indices.astype(np.int64)
    for row in range(incidence.shape[0]):
        columns = np.sort(indices[indptr[row]:indptr[row + 1]])
        key = columns.tobytes()
        counts[key] = counts.get(key, 0) + 1
        sets.setdefault(key, columns)
    members = list(sets.values())
    starts = np.concatenate([[0], np.cumsum([len(m) for m in members])]).astype(np.int64)
    flat = np.concatenate(members).astype(np.int64) if members else np.zeros(0, np.int64)
    return starts, flat, np.array([counts[k] for k in sets], dtype=np.int64)


@numba.njit(cache=True)
def detected_count(indptr, indices, count, visited):
    """Rows (weighted by ``count``) of a CSR incidence holding at least one ``visited`` vertex."""
    total = 0
    for row in range(len(indptr) - 1):
        for e in range(indptr[row], indptr[row + 1]):
            if visited[indices[e]]:
                total += count[row]
                break
    return total
