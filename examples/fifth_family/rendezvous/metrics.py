"""The per-run results, written into the trace so that every sweep can report them."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from .consensus import components

RESULTS = {
    "initial_diameter": "largest distance between two robots at the start [m]",
    "final_diameter": "largest distance between two robots at the end [m]",
    "gathered_step": "first step at which the diameter was at most the tolerance (null if never)",
    "components": "connected components of the sensing graph at the end (1: nobody was lost)",
    "hull_growth": "largest growth of the fleet's convex-hull area over one step [m²]; the theory says 0",
}


def diameter(points: np.ndarray) -> float:
    """Largest pairwise distance (over the hull's vertices when there is one)."""
    if len(points) > 3:
        try:
            points = points[ConvexHull(points).vertices]
        except QhullError:  # all on a line
            pass
    return float(np.max(np.linalg.norm(points[:, None] - points[None], axis=-1))) if len(points) > 1 else 0.0


def hull_area(points: np.ndarray) -> float:
    try:
        return float(ConvexHull(points).volume) if len(points) >= 3 else 0.0
    except QhullError:
        return 0.0


def run_results(positions: np.ndarray, sensing_range: float, tolerance: float) -> dict:
    """The results of a run from its positions ``(T + 1, N, 2)``, ``success`` first."""
    diameters = np.array([diameter(p) for p in positions])
    gathered = np.flatnonzero(diameters <= tolerance)
    areas = np.array([hull_area(p) for p in positions])
    return {
        "success": bool(len(gathered)),
        "initial_diameter": float(diameters[0]),
        "final_diameter": float(diameters[-1]),
        "gathered_step": int(gathered[0]) if len(gathered) else None,
        "components": components(positions[-1], sensing_range),
        "hull_growth": float(max(np.max(np.diff(areas), initial=0.0), 0.0)),
    }
