"""Deadlock-free execution of multi-robot plans under disturbances (paper 000).

RMTRACK (Eq. 1), label flipping (RMTRACK+TFF, RMTRACK+TFA), the segment graph
(Definition 3) with incremental and full cycle tests, the theory checks (Definition 4,
Theorem 4), a revised prioritized planner for the initial plans and the X-plus-corridor
experiment of Fig. 6.
"""

from .coordination_space import CoordinationSpace, build_coordination_space
from .segment_graph import IncrementalCycleDetector, Resolution, SegmentLayout, build_segment_layout, has_cycle_full
from .simulation import ALL_VARIANTS, Estimate, Execution, PlanExecutor, Method, Variant
from .theory import TheoryReport, check_theory
from .trajectories import Trajectories, load_trajectories, make_trajectories, save_trajectories

__all__ = [
    "CoordinationSpace", "build_coordination_space", "IncrementalCycleDetector", "Resolution", "SegmentLayout",
    "build_segment_layout", "has_cycle_full", "ALL_VARIANTS", "Estimate", "Execution", "PlanExecutor", "Method",
    "Variant", "TheoryReport", "check_theory", "Trajectories", "load_trajectories", "make_trajectories",
    "save_trajectories",
]
