"""Shared fixtures and independent checkers for the search tests (paper 002)."""

from __future__ import annotations

import numpy as np
import shapely

from robofleet import load_scenario

TABLE1 = {"r_rob": 0.26, "r_safe": 0.31, "r_so": 1.31, "r_st": 1.31, "r_c": 2.05}

SMALL_AREA = {
    "rectangle": [0, 0, 8, 7],
    "corner_radius": 1.5,
    "obstacles": [
        [[1.8, 1.8], [3.0, 1.8], [3.0, 3.2], [1.8, 3.2]],
        [[4.8, 3.6], [6.0, 4.4], [5.0, 5.2]],
    ],
}


def small_spec(**overrides):
    """A small area where every assumption holds (Table 1 ranges, triangular grid)."""
    data = {
        "family": "search",
        "workspace": SMALL_AREA,
        "grid": {"kind": "triangular", "a": 1.0},
        "ranges": dict(TABLE1),
        "targets": [[1.0, 1.0], [4.0, 6.0], [7.0, 1.5], [4.5, 3.0]],
        "robots": {"count": 3},
        "require_guarantee": True,
    }
    return load_scenario(data, overrides)




def pair_motion_min_distance(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Minimum distance between every pair of robots moving synchronously along straight lines.

    ``p0``, ``p1``: ``(n, 2)`` positions before and after a step (both robots follow the same
    time profile, so the relative position is ``Δp + s Δv`` for ``s ∈ [0, 1]``).
    Returns ``(n, n)`` with ``inf`` on the diagonal.
    """
    dp = p0[:, None, :] - p0[None, :, :]
    dv = (p1 - p0)[:, None, :] - (p1 - p0)[None, :, :]
    vv = np.einsum("ijd,ijd->ij", dv, dv)
    s = np.clip(-np.einsum("ijd,ijd->ij", dp, dv) / np.where(vv > 0, vv, 1.0), 0.0, 1.0)
    d = np.linalg.norm(dp + s[..., None] * dv, axis=-1)
    np.fill_diagonal(d, np.inf)
    return d


def proper_crossings(p0: np.ndarray, p1: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of robots whose move segments intersect (shapely, brute force)."""
    out = []
    moving = np.linalg.norm(p1 - p0, axis=1) > 1e-12
    segs = [shapely.LineString([p0[i], p1[i]]) if moving[i] else shapely.Point(p0[i]) for i in range(len(p0))]
    for i in range(len(p0)):
        for j in range(i + 1, len(p0)):
            if segs[i].intersects(segs[j]):
                out.append((i, j))
    return out


def check_step_invariants(trace, spec) -> None:
    """Section 4 invariants on every step of a recorded run (true positions, brute force)."""
    grid = spec.built_grid()
    verts = trace.arrays["vertex"][:, :, 0]
    pos = trace.positions
    failed_at = {e["robot"]: e["step"] for e in trace.events if e["kind"] == "failure"}
    for k in range(len(verts)):
        assert len(set(verts[k].tolist())) == verts.shape[1], f"two robots on one vertex at step {k}"
        assert grid.accessible[verts[k]].all(), f"a robot on an inaccessible vertex at step {k}"
    for k in range(len(verts) - 1):
        a, b = verts[k], verts[k + 1]
        moved = a != b
        for r in np.flatnonzero(moved):
            slot = np.flatnonzero(grid.neighbours[a[r]] == b[r])
            assert len(slot) == 1, f"robot {r} jumped more than one edge at step {k}"
            assert grid.edge_ok[a[r], slot[0]], f"robot {r} took a blocked edge at step {k}"
            assert r not in failed_at or failed_at[r] > k, f"failed robot {r} moved"
        assert not proper_crossings(pos[k], pos[k + 1]), f"edges shared or crossing at step {k}"
        assert pair_motion_min_distance(pos[k], pos[k + 1]).min() >= 2 * spec.ranges.r_rob, f"bodies touch during step {k}"
