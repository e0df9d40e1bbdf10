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

from .buffer import buffer, confidence_quantile, shadow_epsilon
from .cell import CellGeometry, Cells, Kind, build_cells, cell_from_view
from .guarantees import check
from .obstacles import ObstacleSet, obstacle_planes, wall_planes
from .projection import project_onto_cells
from .safety_filter import FilterResult, RobotSafetyFilter, SafetyFilter
from .separator import gaussian_separator
from .simulation import simulate
from .spec import Spec

__all__ = [
    "Spec", "simulate", "check",
    "gaussian_separator", "build_cells", "cell_from_view", "Cells", "CellGeometry", "Kind",
    "project_onto_cells", "confidence_quantile", "shadow_epsilon", "buffer",
    "ObstacleSet", "obstacle_planes", "wall_planes", "SafetyFilter", "RobotSafetyFilter", "FilterResult",
]
