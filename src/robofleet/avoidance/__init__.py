"""B-UAVC: chance-constrained collision avoidance with buffered uncertainty-aware
Voronoi cells (Zhu, Brito & Alonso-Mora, Autonomous Robots 2022; paper 003).

Public API:

* :func:`gaussian_separator` — appendix B, the minimax separator of two Gaussians;
* :func:`build_cells` / :class:`Cells` — every robot's B-UAVC from current estimates;
* :func:`project_onto_cells` — exact projection of goals onto the cells;
* :func:`confidence_quantile`, :func:`shadow_epsilon` — the chance-constraint constants.
"""

from .buffer import buffer, confidence_quantile, shadow_epsilon
from .cell import CellGeometry, Cells, Kind, build_cells, cell_from_view
from .obstacles import ObstacleSet, obstacle_planes, wall_planes
from .projection import project_onto_cells
from .separator import gaussian_separator

__all__ = [
    "gaussian_separator", "build_cells", "cell_from_view", "Cells", "CellGeometry", "Kind",
    "project_onto_cells", "confidence_quantile", "shadow_epsilon", "buffer",
    "ObstacleSet", "obstacle_planes", "wall_planes",
]
