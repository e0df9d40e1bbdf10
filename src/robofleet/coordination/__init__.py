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

from ..core.lazy import exports

__all__ = [
    "CoordinationSpace", "build_coordination_space", "FAMILY", "TheoryReport", "check", "check_theory",
    "ALL_VARIANTS", "Estimate", "Execution", "Method", "PlanExecutor", "Variant", "IncrementalCycleDetector",
    "Resolution", "SegmentLayout", "build_segment_layout", "has_cycle_full", "simulate", "Spec", "Trajectories",
    "load_trajectories", "make_trajectories", "save_trajectories", "Supervisor", "Answer",
]
__getattr__, __dir__ = exports(__name__, {
    ".coordination_space": ["CoordinationSpace", "build_coordination_space"],
    ".family": ["FAMILY"],
    ".guarantees": ["TheoryReport", "check", "check_theory"],
    ".options": ["Estimate", "Method", "Resolution"],
    ".plan_execution": ["ALL_VARIANTS", "Execution", "PlanExecutor", "Variant"],
    ".segment_graph": ["IncrementalCycleDetector", "SegmentLayout", "build_segment_layout", "has_cycle_full"],
    ".simulation": ["simulate"],
    ".spec": ["Spec"],
    ".supervisor": ["Answer", "Supervisor"],
    ".trajectories": ["Trajectories", "load_trajectories", "make_trajectories", "save_trajectories"],
})
