"""Deadlock-free execution of multi-robot plans under disturbances (the label-flipping deadlock paper (2021)).

RMTRACK (Eq. 1), label flipping (RMTRACK+TFF, RMTRACK+TFA), the segment graph
(Definition 3) with incremental and full cycle tests, the theory checks (Definition 4,
Theorem 4), a revised prioritized planner for the initial plans, the X-plus-corridor
map of Fig. 1 and a warehouse grid; and, on the same instances and loop, the peers of
label flipping: BTPG (:mod:`.btpg`) and the optimal passing orders within a horizon
(:mod:`.optimal`). The family contract: :class:`Spec` (``spec.py``), :func:`simulate`
(``simulation.py``), the per-run results (``metrics.py``), :func:`check`
(``guarantees.py``) and ``FAMILY`` (``family.py``).
"""

from .coordination_space import CoordinationSpace, build_coordination_space
from .family import FAMILY
from .guarantees import TheoryReport, check, check_theory
from .plan_execution import ALL_VARIANTS, Estimate, Execution, Method, PlanExecutor, Variant
from .segment_graph import IncrementalCycleDetector, Resolution, SegmentLayout, build_segment_layout, has_cycle_full
from .simulation import simulate
from .spec import Spec
from .supervisor import Answer, Supervisor
from .trajectories import Trajectories, load_trajectories, make_trajectories, save_trajectories

__all__ = [
    "CoordinationSpace", "build_coordination_space", "FAMILY", "TheoryReport", "check", "check_theory",
    "ALL_VARIANTS", "Estimate", "Execution", "Method", "PlanExecutor", "Variant", "IncrementalCycleDetector",
    "Resolution", "SegmentLayout", "build_segment_layout", "has_cycle_full", "simulate", "Spec", "Trajectories",
    "load_trajectories", "make_trajectories", "save_trajectories", "Supervisor", "Answer",
]
