"""B-UAVC: chance-constrained collision avoidance with buffered uncertainty-aware
Voronoi cells (Zhu, Brito & Alonso-Mora, Autonomous Robots 2022; Zhu et al. 2022).

Public API:

* :class:`Spec`, :func:`simulate`, :func:`check` — the family contract (scenario model,
  the closed loop, the paper's checkable conditions);
* :func:`gaussian_separator` — appendix B, the minimax separator of two Gaussians;
* :func:`build_cells` / :class:`Cells` — every robot's B-UAVC from current estimates;
* :func:`project_onto_cells` — exact projection of goals onto the cells;
* :func:`confidence_quantile`, :func:`shadow_epsilon` — the chance-constraint constants.
"""

from ..core.lazy import exports

__all__ = [
    "Spec", "simulate", "check",
    "gaussian_separator", "build_cells", "cell_from_view", "Cells", "CellGeometry", "Kind",
    "project_onto_cells", "confidence_quantile", "shadow_epsilon", "buffer",
    "ObstacleSet", "obstacle_planes", "wall_planes", "SafetyFilter", "RobotSafetyFilter", "FilterResult",
]
__getattr__, __dir__ = exports(__name__, {
    ".buffer": ["buffer", "confidence_quantile", "shadow_epsilon"],
    ".cell": ["CellGeometry", "Cells", "Kind", "build_cells", "cell_from_view"],
    ".guarantees": ["check"],
    ".obstacles": ["ObstacleSet", "obstacle_planes", "wall_planes"],
    ".projection": ["project_onto_cells"],
    ".safety_filter": ["FilterResult", "RobotSafetyFilter", "SafetyFilter"],
    ".separator": ["gaussian_separator"],
    ".simulation": ["simulate"],
    ".spec": ["Spec"],
})
