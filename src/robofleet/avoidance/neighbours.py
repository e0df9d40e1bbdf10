"""Uniform-grid neighbour search in the plane, compiled, for the cell builder and ORCA.

Points are bucketed into square cells of side ``h``. Two layouts of the same buckets:

* :func:`sort_by_cell` (box neighbours, the cell builder): points sorted by cell key
  ``c_x · rows + c_y`` with two stable counting sorts (by ``c_y``, then ``c_x``), so the
  3×3 cells around a cell are three runs of consecutive keys and a robot's candidates
  are three contiguous slices of the sorted points; a pass over the cells in key order
  finds those runs by moving six cursors forward (:func:`column_runs`), with no hash
  table to probe.
* :func:`build_grid` (k nearest, ORCA): a hash table maps each occupied cell to its run
  in the point order sorted by cell (a counting sort, points of one cell in increasing
  index order).

Building either is O(N); a query visits the few cells around a point, so the
neighbours of all N points cost O(N · k) for k points per neighbourhood — no tree. The
occupied cells, not the bounding box, set the memory: a million robots spread on a
circle of 127 km need one entry per occupied cell.

Every query is per point and reads the grid only, so the queries run in parallel
(``numba.prange``, :mod:`.kernels`) and give the same result whatever the number of
threads; building the grid is serial.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from .kernels import use_parallel

_EMPTY = np.int64(-1)
_CHUNK = 64  # cells per parallel task


class UniformGrid(NamedTuple):
    """Points bucketed into cells of side ``h`` (see the module docstring)."""

    origin: np.ndarray  # (2,) lower corner of the points' bounding box
    h: float
    rows: np.int64  # number of cell rows (c_y range), to make cell keys c_x · rows + c_y
    table_keys: np.ndarray  # (T,) hash table: cell key, -1 where free
    table_cells: np.ndarray  # (T,) hash table: compact cell index
    cell_xy: np.ndarray  # (C, 2) cell coordinates of each compact cell
    start: np.ndarray  # (C + 1,) run of each compact cell in ``order``
    order: np.ndarray  # (N,) point indices sorted by cell (increasing within a cell)
    sorted_points: np.ndarray  # (N, 2) the points in that order (contiguous per cell)


def build_grid(points: np.ndarray, h: float) -> UniformGrid:
    """Bucket ``points (N, 2)`` into cells of side ``h > 0`` (O(N))."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    origin, top = _bounds(pts)
    rows = np.int64(np.floor((top[1] - origin[1]) / h)) + 1
    size = 1 << max(4, int(2 * max(len(pts), 1) - 1).bit_length())  # ≥ 2N slots: short probe chains
    keys, cells, cell_xy, start, order, sorted_points = _build(pts, origin, float(h), rows, size)
    return UniformGrid(origin, float(h), rows, keys, cells, cell_xy, start, order, sorted_points)


@numba.njit(cache=True)
def _bounds(pts):
    """Lower and upper corners of the points' bounding box (zeros for no points)."""
    lo, hi = np.zeros(2), np.zeros(2)
    if len(pts):
        lo[0], lo[1], hi[0], hi[1] = pts[0, 0], pts[0, 1], pts[0, 0], pts[0, 1]
    for i in range(1, len(pts)):
        lo[0], lo[1] = min(lo[0], pts[i, 0]), min(lo[1], pts[i, 1])
        hi[0], hi[1] = max(hi[0], pts[i, 0]), max(hi[1], pts[i, 1])
    return lo, hi


@numba.njit(cache=True, inline="always")
def _slot(key, mask):
    """Home slot of a cell key: the key itself (cells next to each other in y get
    neighbouring slots, so a sweep over nearby cells stays in cache)."""
    return key & mask


@numba.njit(cache=True, inline="always")
def cell_of(x, y, origin, h):
    """Cell coordinates ``(c_x, c_y)`` of a point."""
    return np.int64(np.floor((x - origin[0]) / h)), np.int64(np.floor((y - origin[1]) / h))


@numba.njit(cache=True, inline="always")
def lookup(cx, cy, rows, table_keys, table_cells):
    """Compact index of cell ``(c_x, c_y)``, or -1 if no point lies in it."""
    if cy < 0 or cy >= rows or cx < 0:
        return -1
    key = cx * rows + cy
    mask = len(table_keys) - 1
    s = _slot(key, mask)
    while table_keys[s] != -1:
        if table_keys[s] == key:
            return table_cells[s]
        s = (s + 1) & mask
    return -1


@numba.njit(cache=True)
def _build(pts, origin, h, rows, size):
    n = len(pts)
    table_keys = np.full(size, _EMPTY, np.int64)
    table_cells = np.empty(size, np.int64)
    cell = np.empty(n, np.int64)
    cell_xy = np.empty((n, 2), np.int64)
    mask = size - 1
    count = 0
    for i in range(n):
        cx, cy = cell_of(pts[i, 0], pts[i, 1], origin, h)
        key = cx * rows + cy
        s = _slot(key, mask)
        while table_keys[s] != -1 and table_keys[s] != key:
            s = (s + 1) & mask
        if table_keys[s] == -1:
            table_keys[s] = key
            table_cells[s] = count
            cell_xy[count, 0], cell_xy[count, 1] = cx, cy
            count += 1
        cell[i] = table_cells[s]
    start = np.zeros(count + 1, np.int64)
    for i in range(n):
        start[cell[i] + 1] += 1
    for c in range(count):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    sorted_points = np.empty((n, 2))
    for i in range(n):
        m = fill[cell[i]]
        order[m] = i
        sorted_points[m, 0], sorted_points[m, 1] = pts[i, 0], pts[i, 1]
        fill[cell[i]] = m + 1
    return table_keys, table_cells, cell_xy[:count].copy(), start, order, sorted_points


@numba.njit(cache=True, inline="always")
def around(c, reach, rows, table_keys, table_cells, cell_xy, runs):
    """Compact indices of the (2·reach + 1)² cells around cell ``c`` (-1 where empty)."""
    cx, cy = cell_xy[c, 0], cell_xy[c, 1]
    k = 0
    for ax in range(cx - reach, cx + reach + 1):
        for ay in range(cy - reach, cy + reach + 1):
            runs[k] = lookup(ax, ay, rows, table_keys, table_cells)
            k += 1


# ---------------------------------------------------------------------------------------
# box neighbours (the cell builder: |p_i − p_j|_∞ ≤ R_loc): points sorted by cell key
# ---------------------------------------------------------------------------------------
class CellRuns(NamedTuple):
    """Points sorted by cell key ``c_x · rows + c_y`` (column-major, ties by index): the
    3×3 cells around a cell are three runs of consecutive keys, one per column, so a
    robot's box neighbours are read from three contiguous slices of ``sorted_points``
    found by binary search over the occupied keys, with no hash table to probe."""

    rows: np.int64  # number of cell rows (c_y range)
    cell_key: np.ndarray  # (C,) occupied cell keys, increasing
    start: np.ndarray  # (C + 1,) run of each occupied cell in ``order``
    order: np.ndarray  # (N,) point indices sorted by (cell key, index)
    sorted_points: np.ndarray  # (N, 2) the points in that order


def sort_by_cell(points: np.ndarray, h: float) -> CellRuns:
    """Sort ``points (N, 2)`` by the key of their cell of side ``h > 0`` (O(N): two stable
    counting-sort passes, by c_y then c_x, when the bounding box spans at most a few N
    cells per axis; a stable comparison sort of the keys otherwise)."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    origin, top = _bounds(pts)
    cols, rows = (np.int64(np.floor((top[a] - origin[a]) / h)) + 1 for a in (0, 1))
    cx, cy = _cell_coordinates(pts, origin, float(h))
    if max(cols, rows) <= 4 * len(pts) + 1024:
        order = _counting_sort(cx, cols, _counting_sort(cy, rows, np.arange(len(pts))))
    else:
        order = np.argsort(cx * rows + cy, kind="stable")
    cell_key, start, sorted_points = _runs(pts, order, cx, cy, rows)
    return CellRuns(rows, cell_key, start, order, sorted_points)


@numba.njit(cache=True)
def _cell_coordinates(pts, origin, h):
    cx, cy = np.empty(len(pts), np.int64), np.empty(len(pts), np.int64)
    for i in range(len(pts)):
        cx[i], cy[i] = cell_of(pts[i, 0], pts[i, 1], origin, h)
    return cx, cy


@numba.njit(cache=True)
def _counting_sort(digit, buckets, order):
    """``order`` stably re-sorted by ``digit[order]`` (values in ``0 … buckets − 1``)."""
    start = np.zeros(buckets + 1, np.int64)
    for i in order:
        start[digit[i] + 1] += 1
    for c in range(buckets):
        start[c + 1] += start[c]
    out = np.empty(len(order), np.int64)
    for i in order:
        out[start[digit[i]]] = i
        start[digit[i]] += 1
    return out


@numba.njit(cache=True)
def _runs(pts, order, cx, cy, rows):
    """Occupied keys, their runs in ``order`` and the sorted points."""
    n = len(order)
    cell_key = np.empty(n, np.int64)
    start = np.empty(n + 1, np.int64)
    sorted_points = np.empty((n, 2))
    cells = 0
    for m in range(n):
        i = order[m]
        key = cx[i] * rows + cy[i]
        if cells == 0 or cell_key[cells - 1] != key:
            cell_key[cells], start[cells] = key, m
            cells += 1
        sorted_points[m, 0], sorted_points[m, 1] = pts[i, 0], pts[i, 1]
    start[cells] = n
    return cell_key[:cells].copy(), start[:cells + 1].copy(), sorted_points


@numba.njit(cache=True, inline="always")
def column_runs(c, rows, cell_key, cstart, cursor, fresh, runs):
    """The runs ``[runs[2q], runs[2q + 1])`` of sorted points in column ``c_x + q − 1`` and
    rows ``c_y − 1 … c_y + 1`` (clipped to the grid) around occupied cell ``c``.

    ``cursor (6,)`` holds the occupied-cell bounds of those runs. Both bounds of every
    column grow with the key, so a pass over cells in increasing order moves them forward
    from the previous cell's; ``fresh`` (the first cell of a pass) finds them by binary
    search instead."""
    key = cell_key[c]
    cy = key % rows
    below, above = max(cy - 1, 0) - cy, min(cy + 1, rows - 1) - cy
    for q in range(3):
        centre = key + (q - 1) * rows
        if fresh:
            cursor[2 * q] = np.searchsorted(cell_key, centre + below)
            cursor[2 * q + 1] = np.searchsorted(cell_key, centre + above, side="right")
        else:
            cursor[2 * q] = _first_at_least(cell_key, cursor[2 * q], centre + below)
            cursor[2 * q + 1] = _first_at_least(cell_key, max(cursor[2 * q + 1], cursor[2 * q]), centre + above + 1)
        runs[2 * q], runs[2 * q + 1] = cstart[cursor[2 * q]], cstart[cursor[2 * q + 1]]


@numba.njit(cache=True, inline="always")
def _first_at_least(keys, k, target):
    """The first index from ``k`` on whose key is at least ``target`` (``len(keys)`` if none)."""
    while k < len(keys) and keys[k] < target:
        k += 1
    return k


def box_neighbours(points: np.ndarray, half_width: float) -> tuple[np.ndarray, np.ndarray]:
    """For every point, the other points ``j`` with ``‖p_i − p_j‖_∞ ≤ half_width``, in CSR
    form: ``(start (N + 1,), index (start[-1],))``, each point's neighbours in increasing
    index order. O(N · k); the cells have side ``half_width``, so 3×3 cells hold them all.
    (The cell builder gathers the same neighbours inside its own kernel, :func:`box_gather`.)"""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if len(pts) == 0:
        return np.zeros(1, np.int64), np.zeros(0, np.int64)
    g = sort_by_cell(pts, half_width)
    start = np.zeros(len(pts) + 1, np.int64)
    _box_csr(half_width, *g, start, np.empty(0, np.int64), False)
    np.cumsum(start[1:], out=start[1:])
    index = np.empty(start[-1], np.int64)
    _box_csr(half_width, *g, start, index, True)
    return start, index


@numba.njit(cache=True)
def _box_csr(r, rows, cell_key, cstart, order, spts, start, index, write):
    """Count each point's box neighbours into ``start[i]`` or (``write``) store them sorted."""
    runs, cursor = np.empty(6, np.int64), np.empty(6, np.int64)
    buf = np.empty(len(order), np.int64)  # serial: one buffer large enough for any point
    for c in range(len(cstart) - 1):
        column_runs(c, rows, cell_key, cstart, cursor, c == 0, runs)
        for m in range(cstart[c], cstart[c + 1]):
            k = box_gather(m, r, runs, order, spts, buf)
            i = order[m]
            if write:
                insertion_sort(buf[:k])
                index[start[i]:start[i] + k] = buf[:k]
            else:
                start[i + 1] = k


@numba.njit(cache=True, inline="always")
def box_gather(m, r, runs, order, spts, out):
    """The box neighbours (``‖·‖_∞ ≤ r``) of sorted point ``m`` into ``out`` (unsorted, as many
    as fit), with ``runs`` the three column runs around its cell (:func:`column_runs`);
    returns their count."""
    x, y = spts[m, 0], spts[m, 1]
    k = 0
    for q in range(3):
        for mm in range(runs[2 * q], runs[2 * q + 1]):
            if mm != m and max(abs(spts[mm, 0] - x), abs(spts[mm, 1] - y)) <= r:
                if k < len(out):
                    out[k] = order[mm]
                k += 1
    return k


@numba.njit(cache=True, inline="always")
def insertion_sort(values):
    """Sort a short array in place (a handful of neighbours per point)."""
    for a in range(1, len(values)):
        v = values[a]
        b = a - 1
        while b >= 0 and values[b] > v:
            values[b + 1] = values[b]
            b -= 1
        values[b + 1] = v


# ---------------------------------------------------------------------------------------
# k nearest neighbours within a range (ORCA)
# ---------------------------------------------------------------------------------------
_KNN_REACH = 2  # cells of side max_dist / 2: points closer than max_dist lie within 2 cells


def nearest_neighbours(points: np.ndarray, k: int, max_dist: float) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``k`` nearest other points with ``‖p_i − p_j‖ < max_dist``, for every point.

    Returns ``index (N, k)`` (nearest first; ties by index; ``-1`` past the count) and
    ``count (N,)``. Cells of side ``max_dist / 2``; each point scans its own and the 8
    surrounding cells, then the next ring only if its k-th distance so far is not below
    the ring's distance.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    n = len(pts)
    index = np.full((n, max(k, 0)), -1, np.int64)
    count = np.zeros(n, np.int64)
    if n < 2 or k <= 0:
        return index, count
    g = build_grid(pts, 0.5 * max_dist)
    args = (k, max_dist * max_dist, g.h, g.rows, g.table_keys, g.table_cells, g.cell_xy, g.start, g.order, g.sorted_points, index, count)
    if use_parallel(n):
        _knn_parallel(*args)
    else:
        _knn_cells(0, len(g.start) - 1, *args)
    return index, count


@numba.njit(cache=True, parallel=True)
def _knn_parallel(k, range_sq, h, rows, table_keys, table_cells, cell_xy, cstart, order, spts, index, count):
    cells = len(cstart) - 1
    for c in numba.prange((cells + _CHUNK - 1) // _CHUNK):
        _knn_cells(c * _CHUNK, min(cells, (c + 1) * _CHUNK), k, range_sq, h, rows, table_keys, table_cells, cell_xy, cstart, order, spts, index, count)


@numba.njit(cache=True)
def _knn_cells(lo, hi, k, range_sq, h, rows, table_keys, table_cells, cell_xy, cstart, order, spts, index, count):
    """The k nearest of every point of cells ``lo … hi − 1``."""
    width = 2 * _KNN_REACH + 1
    runs = np.empty(width * width, np.int64)
    dist = np.empty(k)
    for c in range(lo, hi):
        around(c, _KNN_REACH, rows, table_keys, table_cells, cell_xy, runs)
        for m in range(cstart[c], cstart[c + 1]):
            i = order[m]
            count[i] = _knn_one(m, k, range_sq, h, runs, cstart, order, spts, index[i], dist)


@numba.njit(cache=True)
def _knn_one(m, k, range_sq, h, runs, cstart, order, spts, out, dist):
    """The ``k`` nearest of sorted point ``m`` into ``out`` (by ``(distance², index)``); returns the count."""
    x, y = spts[m, 0], spts[m, 1]
    width = 2 * _KNN_REACH + 1
    found = 0
    for ring in range(_KNN_REACH + 1):
        bound = max(ring - 1, 0) * h  # every point of this ring is at least this far
        if bound * bound >= range_sq or (found == k and bound * bound > dist[k - 1]):
            break
        for ax in range(-ring, ring + 1):
            step = 1 if (ax == -ring or ax == ring) else 2 * ring
            for ay in range(-ring, ring + 1, max(step, 1)):
                cc = runs[(ax + _KNN_REACH) * width + ay + _KNN_REACH]
                if cc < 0:
                    continue
                for mm in range(cstart[cc], cstart[cc + 1]):
                    if mm == m:
                        continue
                    dx, dy = spts[mm, 0] - x, spts[mm, 1] - y
                    d2 = dx * dx + dy * dy
                    j = order[mm]
                    if d2 >= range_sq or (found == k and (d2 > dist[k - 1] or (d2 == dist[k - 1] and j > out[k - 1]))):
                        continue
                    found = _insert(out, dist, found, k, j, d2)
    return found


@numba.njit(cache=True, inline="always")
def _insert(out, dist, found, k, j, d2):
    """Insert ``(d2, j)`` into the sorted top-k lists; returns the new count."""
    pos = min(found, k - 1)
    while pos > 0 and (dist[pos - 1] > d2 or (dist[pos - 1] == d2 and out[pos - 1] > j)):
        out[pos], dist[pos] = out[pos - 1], dist[pos - 1]
        pos -= 1
    out[pos], dist[pos] = j, d2
    return min(found + 1, k)


# ---------------------------------------------------------------------------------------
# a growing point set with "is any point closer than gap?" queries (layout sampling)
# ---------------------------------------------------------------------------------------
class PointGrid:
    """Points inserted one by one into cells of side a little above ``gap``, so that a
    candidate's points closer than ``gap`` all lie in the 3×3 cells around it: each
    query and insertion is O(1) for bounded density (a hash table of cells with a linked
    list of points per cell). Used by the rejection samplers of random layouts."""

    def __init__(self, capacity: int, gap: float):
        size = 1 << max(4, int(4 * max(capacity, 1) - 1).bit_length())
        self.gap = float(gap)
        self.h = float(gap) * (1.0 + 1e-9) if gap > 0 else 1.0
        self.keys = np.full((size, 2), np.iinfo(np.int64).min, np.int64)
        self.head = np.full(size, -1, np.int64)
        self.next = np.full(max(capacity, 1), -1, np.int64)
        self.points = np.empty((max(capacity, 1), 2))
        self.count = np.zeros(1, np.int64)

    def accept_run(self, first: np.ndarray, second: np.ndarray, admissible: np.ndarray) -> int:
        """Walk candidates ``k = 0, 1, …`` (each the two points ``first[k]``, ``second[k]``):
        insert both while ``admissible[k]`` and neither lies closer than ``gap`` to a point
        already in the set; return the index of the first refused candidate (or the count)."""
        return int(_accept_run(np.ascontiguousarray(first, dtype=np.float64), np.ascontiguousarray(second, dtype=np.float64),
                               np.ascontiguousarray(admissible, dtype=np.bool_), self.gap, self.h, self.keys, self.head, self.next,
                               self.points, self.count))


@numba.njit(cache=True)
def _cell_slot(cx, cy, keys, insert):
    mask = len(keys) - 1
    s = np.int64((np.uint64(cx) * np.uint64(0x9E3779B97F4A7C15) ^ np.uint64(cy) * np.uint64(0xC2B2AE3D27D4EB4F)) >> np.uint64(17)) & mask
    while True:
        if keys[s, 0] == cx and keys[s, 1] == cy:
            return s
        if keys[s, 0] == np.iinfo(np.int64).min:
            if insert:
                keys[s, 0], keys[s, 1] = cx, cy
                return s
            return -1
        s = (s + 1) & mask


@numba.njit(cache=True)
def _too_close(x, y, gap, h, keys, head, nxt, points):
    cx, cy = np.int64(np.floor(x / h)), np.int64(np.floor(y / h))
    for ax in range(cx - 1, cx + 2):
        for ay in range(cy - 1, cy + 2):
            s = _cell_slot(ax, ay, keys, False)
            if s < 0:
                continue
            k = head[s]
            while k >= 0:
                dx, dy = points[k, 0] - x, points[k, 1] - y
                if np.sqrt(dx * dx + dy * dy) < gap:
                    return True
                k = nxt[k]
    return False


@numba.njit(cache=True)
def _insert_point(x, y, h, keys, head, nxt, points, count):
    k = count[0]
    points[k, 0], points[k, 1] = x, y
    s = _cell_slot(np.int64(np.floor(x / h)), np.int64(np.floor(y / h)), keys, True)
    nxt[k], head[s] = head[s], k
    count[0] = k + 1


@numba.njit(cache=True)
def _accept_run(first, second, admissible, gap, h, keys, head, nxt, points, count):
    for k in range(len(first)):
        if not admissible[k]:
            return k
        if (_too_close(first[k, 0], first[k, 1], gap, h, keys, head, nxt, points)
                or _too_close(second[k, 0], second[k, 1], gap, h, keys, head, nxt, points)):
            return k
        _insert_point(first[k, 0], first[k, 1], h, keys, head, nxt, points, count)
        _insert_point(second[k, 0], second[k, 1], h, keys, head, nxt, points, count)
    return len(first)
