"""Leader-following flocking of oblivious, anonymous, asynchronous robots.

Implements V. Gervasi and G. Prencipe, "Flocking by a set of autonomous mobile robots"
(Univ. of Pisa TR-01-24, 2001): the Look-Compute-Move model with FSYNC, SSYNC and ASYNC
schedulers (:mod:`.schedulers`), local frames and snapshots (:mod:`.model`), the
leader's course and the conditions (1)-(4) of Sec. 3.2 (:mod:`.leader`), the basic
Algorithm 1 (:mod:`.basic`), the hula-hoop (:mod:`.hula_hoop`, Sec. 5.2) and stripe
(:mod:`.stripe`, Sec. 5.3) variants, randomized tie breaking (:mod:`.randomized`,
Sec. 6.4), the variants with more common knowledge (:mod:`.knowledge`, Sec. 6),
patterns (:mod:`.patterns`, Fig. 8) and metrics (:mod:`.metrics`, Defs. 3.1-3.3 and
Sec. 4.2). Scenario files use ``family: flocking`` (:mod:`.spec`); :mod:`.simulation` is
the run loop, :mod:`.guarantees` the paper's checkable conditions, :mod:`.family` the
family's entry in the table.

In every trace of this family, robot index 0 is the leader and indices ``1..m`` are the
followers.
"""

from ..core.lazy import exports

__all__ = [
    "BasicAlgorithm", "StripeAlgorithm", "HulaHoopAlgorithm", "RandomizedAlgorithm", "ranking",
    "ObservableHeadingAlgorithm", "MemoryAlgorithm", "ChiralityAlgorithm", "SharedAxesAlgorithm",
    "LocalFrames", "Snapshot", "Decision", "look", "SchedulerSpec", "LookComputeMove", "run", "Spec", "simulate",
    "LeaderCourse", "check_conditions", "FlockingConditionWarning",
    "Pattern", "make_pattern", "validate_points",
    "d_distance", "delta_series", "estimated_target", "real_target", "convergence_time",
]
__getattr__, __dir__ = exports(__name__, {
    ".basic": ["BasicAlgorithm"],
    ".hula_hoop": ["HulaHoopAlgorithm"],
    ".knowledge": ["ChiralityAlgorithm", "MemoryAlgorithm", "ObservableHeadingAlgorithm", "SharedAxesAlgorithm"],
    ".leader": ["FlockingConditionWarning", "LeaderCourse", "check_conditions"],
    ".metrics": ["convergence_time", "d_distance", "delta_series", "estimated_target", "real_target"],
    ".model": ["Decision", "LocalFrames", "Snapshot", "look"],
    ".patterns": ["Pattern", "make_pattern", "validate_points"],
    ".randomized": ["RandomizedAlgorithm", "ranking"],
    ".schedulers": ["LookComputeMove", "run"], ".scheduler_spec": ["SchedulerSpec"],
    ".simulation": ["simulate"],
    ".spec": ["Spec"],
    ".stripe": ["StripeAlgorithm"],
})
