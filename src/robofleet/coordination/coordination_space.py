"""Coordination-space obstacles of every robot pair (the label-flipping deadlock paper (2021), "Summary of baseline approaches").

For robots ``i < j`` the obstacle region is
``O_ij = {(k_i, k_j) : ‖π_i(k_i) − π_j(k_j)‖ < 2r}``; its 4-connected components are the
coordination-space obstacles ``o_ij^k``. Each obstacle is stored as two *sides*, one per
robot that may have to wait for it:

* side ``2k`` — waiter ``i``: for each column ``k_i ∈ [L_i, R_i]`` the highest row
  ``top(k_i)`` (what Eq. 1 tests when the label is ``j``);
* side ``2k + 1`` — waiter ``j``: for each row ``k_j ∈ [B_j, T_j]`` the rightmost column
  ``right(k_j)`` (Eq. 1 with the roles exchanged, label ``i``).

A side is *active* when the obstacle's label is the other robot. Profiles of all sides
are concatenated into one flat array so that Eq. 1 is evaluated for all robots with a
handful of numpy operations (:mod:`~robofleet.coordination.rmtrack`).

Construction cost: a naive grid is ``O(K_i K_j)`` per pair. Here trajectories are cut in
windows of ``window`` steps; only window pairs whose swept bounding boxes come closer than
``2r`` are expanded into distance blocks, and pairs whose whole trajectories' boxes are
apart are skipped before that.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..core import arguments
from ..core.errors import InfeasibleError
from .trajectories import Trajectories


@dataclass(frozen=True)
class CoordinationSpace:
    """All coordination-space obstacles of a plan.

    Attributes (``m`` obstacles, ``2m`` sides)
    ------------------------------------------
    lengths: ``(n,)`` the ``K_i``.
    robot_i, robot_j: ``(m,)`` the pair of each obstacle (``i < j``).
    initial_labels: ``(m,)`` robot that passes first in the plan (``ℓ(o)``).
    side_waiter, side_other: ``(2m,)`` robot that waits on the side / the robot it waits for.
    side_lo, side_hi: ``(2m,)`` waiter's step range of the obstacle (``[L_i, R_i]`` or ``[B_j, T_j]``).
    side_other_lo, side_other_hi: ``(2m,)`` the other robot's step range.
    side_offset: ``(2m,)`` start of the side's profile in ``profile``.
    profile: flat int array; ``profile[side_offset[s] + c - side_lo[s]]`` is the highest step of the other robot inside the obstacle at waiter step ``c``.
    n_cells: ``(m,)`` number of grid cells of each obstacle.
    """

    lengths: np.ndarray
    robot_i: np.ndarray
    robot_j: np.ndarray
    initial_labels: np.ndarray
    side_waiter: np.ndarray
    side_other: np.ndarray
    side_lo: np.ndarray
    side_hi: np.ndarray
    side_other_lo: np.ndarray
    side_other_hi: np.ndarray
    side_offset: np.ndarray
    profile: np.ndarray
    n_cells: np.ndarray

    @property
    def n_robots(self) -> int:
        return int(len(self.lengths))

    @property
    def n_obstacles(self) -> int:
        return int(len(self.robot_i))

    @cached_property
    def side_obstacle(self) -> np.ndarray:
        return np.repeat(np.arange(self.n_obstacles), 2)

    def side_profile(self, side: int) -> np.ndarray:
        """Profile of one side (highest other-robot step per waiter step)."""
        n = int(self.side_hi[side] - self.side_lo[side] + 1)
        return self.profile[self.side_offset[side]: self.side_offset[side] + n]

    def side_of(self, obstacle: int, waiter: int) -> int:
        """Index of the side of ``obstacle`` on which ``waiter`` waits."""
        return 2 * obstacle + int(self.robot_j[obstacle] == waiter)


def build_coordination_space(traj: Trajectories, window: int = 32, check_plan: bool = True) -> CoordinationSpace:
    """Compute every coordination-space obstacle of a plan.

    Complexity: ``O(n²)`` box tests, then ``O(w²)`` distances only per close window pair.

    Parameters
    ----------
    traj:
        the plan.
    window:
        steps per window for the swept-bounding-box pruning.
    check_plan:
        raise if the plan itself collides (labels would be undefined).

    Returns
    -------
    CoordinationSpace
        with labels initialised from the plan: ``ℓ(o) = i`` when every cell
        ``(k_i, k_j)`` of ``o`` has ``k_i < k_j`` (robot ``i`` is there first in plan time).

    Raises
    ------
    InfeasibleError
        When the plan collides (some obstacle is crossed by the plan's own path).
    ConfigError
        When ``traj`` is not a :class:`Trajectories`, ``window`` not an integer ≥ 1 or
        ``check_plan`` not a bool (input validation).
    """
    arguments.instance(traj, Trajectories, "traj", "a Trajectories plan (load_trajectories, make_trajectories)")
    window = arguments.count(window, "window", minimum=1)
    arguments.flag(check_plan, "check_plan")
    return space_of_cells(traj, pair_cells(traj, window), check_plan)


def pair_cells(traj: Trajectories, window: int = 32, robot: int | None = None) -> dict[tuple[int, int], np.ndarray]:
    """The cells ``(k_i, k_j)`` of ``O_ij`` (int ``(c, 2)``) of every pair ``i < j`` that has
    some (of every such pair with ``robot`` when given).

    A pair's cells depend on nothing but the two robots' plans up to their goal steps (a
    window pair is skipped only when its boxes, which hold those steps, are ``2r`` apart,
    and then so are all its cells): after a change of one robot's plan the other pairs'
    cells are those of the old plan (:meth:`~.supervisor.Supervisor.append_plan`)."""
    boxes = _window_boxes(traj, window)
    reach = 2.0 * traj.radius
    cells = {}
    for i, j in _candidate_pairs(traj, reach):
        if robot is None or robot in (i, j):
            c = _close_cells(traj, boxes, window, reach, i, j)
            if len(c):
                cells[(i, j)] = c
    return cells


def space_of_cells(traj: Trajectories, cells_of_pair: dict[tuple[int, int], np.ndarray], check_plan: bool = True) -> CoordinationSpace:
    """The coordination space of ``traj`` from the cells of its pairs (:func:`pair_cells`)."""
    pairs = sorted(cells_of_pair)
    if not pairs:
        return _empty_space(traj.lengths)
    cells = [cells_of_pair[pair] for pair in pairs]
    pair_of_cell = [np.full(len(c), k) for k, c in enumerate(cells)]
    cells, pair_of_cell = np.concatenate(cells), np.concatenate(pair_of_cell)
    comp, first_cell = _components(cells, pair_of_cell, int(traj.lengths.max()))
    pairs = np.asarray(pairs)
    return _assemble(traj, cells, comp, pairs[pair_of_cell[first_cell]], check_plan)


def _window_boxes(traj: Trajectories, window: int) -> np.ndarray:
    """Swept bounding boxes ``(n, n_windows, 4)`` = (xmin, ymin, xmax, ymax) per window."""
    n, k1, _ = traj.positions.shape
    n_win = -(-k1 // window)
    pad = np.concatenate([traj.positions, np.repeat(traj.positions[:, -1:], n_win * window - k1, axis=1)], axis=1)
    win = pad.reshape(n, n_win, window, 2)
    return np.concatenate([win.min(axis=2), win.max(axis=2)], axis=-1)


def _candidate_pairs(traj: Trajectories, reach: float) -> list[tuple[int, int]]:
    """Pairs whose whole-trajectory boxes come closer than ``reach``."""
    lo, hi = traj.positions.min(axis=1), traj.positions.max(axis=1)
    gap = np.maximum(lo[:, None] - hi[None, :], lo[None, :] - hi[:, None]).max(axis=-1)
    i, j = np.nonzero(np.triu(gap < reach, k=1))
    return list(zip(i.tolist(), j.tolist()))


def _close_cells(traj: Trajectories, boxes: np.ndarray, window: int, reach: float, i: int, j: int) -> np.ndarray:
    """Cells ``(k_i, k_j)`` of ``O_ij`` (int ``(c, 2)``), only in close window pairs."""
    bi, bj = boxes[i], boxes[j]
    gap = np.maximum(bi[:, None, :2] - bj[None, :, 2:], bj[None, :, :2] - bi[:, None, 2:]).max(axis=-1)
    wa, wb = np.nonzero(gap < reach)
    if len(wa) == 0:
        return np.empty((0, 2), dtype=np.intp)
    ki = wa[:, None] * window + np.arange(window)[None, :]
    kj = wb[:, None] * window + np.arange(window)[None, :]
    ki_c = np.minimum(ki, traj.positions.shape[1] - 1)
    kj_c = np.minimum(kj, traj.positions.shape[1] - 1)
    pi, pj = traj.positions[i, ki_c], traj.positions[j, kj_c]
    dx = pi[:, :, None, 0] - pj[:, None, :, 0]
    dy = pi[:, :, None, 1] - pj[:, None, :, 1]
    d2 = dx * dx + dy * dy
    hit = (d2 < reach * reach) & (ki[:, :, None] <= traj.lengths[i]) & (kj[:, None, :] <= traj.lengths[j])
    p, a, b = np.nonzero(hit)
    return np.column_stack([ki[p, a], kj[p, b]])


def _components(cells: np.ndarray, pair_of_cell: np.ndarray, k_max: int) -> tuple[np.ndarray, np.ndarray]:
    """4-connected components of the cells of all pairs at once (one sparse graph).

    Returns the component of every cell (numbered by pair, then by the lowest ``(k_i, k_j)``
    cell) and the index of each component's first cell.
    """
    width = k_max + 2  # > K + 1: neighbours never wrap into another column or pair
    keys = (pair_of_cell.astype(np.int64) * width + cells[:, 0]) * width + cells[:, 1]
    order = np.argsort(keys)
    keys = keys[order]
    src, dst = [], []
    for step in (1, width):  # neighbour up (k_j + 1) and right (k_i + 1)
        pos = np.searchsorted(keys, keys + step)
        ok = pos < len(keys)
        ok[ok] &= keys[pos[ok]] == keys[ok] + step
        src.append(np.flatnonzero(ok))
        dst.append(pos[ok])
    src, dst = np.concatenate(src), np.concatenate(dst)
    adj = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(len(keys), len(keys)))
    _, sorted_comp = connected_components(adj, directed=False)
    first = np.full(sorted_comp.max() + 1, len(keys), dtype=np.intp)
    np.minimum.at(first, sorted_comp, np.arange(len(keys)))
    rank = np.argsort(first, kind="stable")  # number components by (pair, k_i, k_j) of their first cell
    relabel = np.empty_like(rank)
    relabel[rank] = np.arange(len(rank))
    comp = np.empty(len(keys), dtype=np.intp)
    comp[order] = relabel[sorted_comp]
    return comp, order[first[rank]]


def _assemble(traj: Trajectories, cells: np.ndarray, comp: np.ndarray, pair_of_comp: np.ndarray, check_plan: bool) -> CoordinationSpace:
    """Ranges, profiles and plan labels of every obstacle, vectorized over all cells."""
    m = len(pair_of_comp)
    robot_i, robot_j = pair_of_comp[:, 0], pair_of_comp[:, 1]
    ki, kj = cells[:, 0], cells[:, 1]
    lo_i, hi_i = _group_min(comp, ki, m), _group_max(comp, ki, m)
    lo_j, hi_j = _group_min(comp, kj, m), _group_max(comp, kj, m)
    if check_plan:
        _raise_on_plan_collision(cells, comp, robot_i, robot_j, traj.lengths)
    lead_max = _group_max(comp, ki - kj, m)
    labels = np.where(lead_max < 0, robot_i, robot_j)
    # sides: 2k waiter i over columns (profile = top row), 2k+1 waiter j over rows (profile = right column)
    side_lo = np.column_stack([lo_i, lo_j]).ravel()
    side_hi = np.column_stack([hi_i, hi_j]).ravel()
    sizes = side_hi - side_lo + 1
    offset = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    profile = np.full(int(sizes.sum()), -1, dtype=np.intp)
    np.maximum.at(profile, offset[2 * comp] + ki - lo_i[comp], kj)
    np.maximum.at(profile, offset[2 * comp + 1] + kj - lo_j[comp], ki)
    n_cells = np.bincount(comp, minlength=m)
    return CoordinationSpace(
        lengths=traj.lengths.copy(),
        robot_i=robot_i, robot_j=robot_j, initial_labels=labels,
        side_waiter=np.column_stack([robot_i, robot_j]).ravel(),
        side_other=np.column_stack([robot_j, robot_i]).ravel(),
        side_lo=side_lo, side_hi=side_hi,
        side_other_lo=np.column_stack([lo_j, lo_i]).ravel(),
        side_other_hi=np.column_stack([hi_j, hi_i]).ravel(),
        side_offset=offset, profile=profile, n_cells=n_cells,
    )


def _raise_on_plan_collision(cells, comp, robot_i, robot_j, lengths) -> None:
    """Raise if a cell lies on the plan's own path ``(min(t, K_i), min(t, K_j))``.

    A 4-connected obstacle that avoids this (8-connected, monotone) path lies entirely on
    one side of it, so the plan order then defines its label.
    """
    ki, kj = cells[:, 0], cells[:, 1]
    Ki, Kj = lengths[robot_i[comp]], lengths[robot_j[comp]]
    on_path = (ki == kj) | ((ki == Ki) & (kj > Ki)) | ((kj == Kj) & (ki > Kj))
    if on_path.any():
        c = int(np.flatnonzero(on_path)[0])
        i, j, t = int(robot_i[comp[c]]), int(robot_j[comp[c]]), int(max(ki[c], kj[c]))
        raise InfeasibleError(
            f"trajectories: expected a collision-free plan, received robots {i} and {j} closer than 2r at plan step {t}"
        )


def _group_min(group: np.ndarray, values: np.ndarray, m: int) -> np.ndarray:
    out = np.full(m, np.iinfo(np.intp).max, dtype=np.intp)
    np.minimum.at(out, group, values)
    return out


def _group_max(group: np.ndarray, values: np.ndarray, m: int) -> np.ndarray:
    out = np.full(m, np.iinfo(np.intp).min, dtype=np.intp)
    np.maximum.at(out, group, values)
    return out


def _empty_space(lengths: np.ndarray) -> CoordinationSpace:
    e = np.empty(0, dtype=np.intp)
    return CoordinationSpace(lengths.copy(), e, e, e, e, e, e, e, e, e, e, e, e)


def obstacle_grid(traj: Trajectories, i: int, j: int) -> np.ndarray:
    """Dense boolean grid ``(K_i + 1, K_j + 1)`` of ``O_ij`` (reference and plotting only)."""
    pi = traj.positions[i, : traj.lengths[i] + 1]
    pj = traj.positions[j, : traj.lengths[j] + 1]
    d = np.linalg.norm(pi[:, None] - pj[None], axis=-1)
    return d < 2.0 * traj.radius
