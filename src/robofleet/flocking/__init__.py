"""Leader-following flocking of oblivious, anonymous, asynchronous robots.

Implements V. Gervasi and G. Prencipe, "Flocking by a set of autonomous mobile robots"
(Univ. of Pisa TR-01-24, 2001): the Look-Compute-Move model with FSYNC, SSYNC and ASYNC
schedulers (:mod:`.schedulers`), local frames and snapshots (:mod:`.model`), the
leader's course and the conditions (1)-(4) of Sec. 3.2 (:mod:`.leader`), the basic
Algorithm 1 (:mod:`.basic`), the hula-hoop (:mod:`.hula_hoop`, Sec. 5.2) and stripe
(:mod:`.stripe`, Sec. 5.3) variants, randomized tie breaking (:mod:`.randomized`,
Sec. 6.4), the variants with more common knowledge (:mod:`.knowledge`, Sec. 6),
patterns (:mod:`.patterns`, Fig. 8) and metrics (:mod:`.metrics`, Defs. 3.1-3.3 and
Sec. 4.2). Scenario files use ``family: flocking`` (:mod:`.scenario`).

In every trace of this family, robot index 0 is the leader and indices ``1..m`` are the
followers.
"""

from .metrics import d_distance, delta_series, estimated_target, real_target
from .patterns import Pattern, make_pattern

__all__ = ["Pattern", "make_pattern", "d_distance", "delta_series", "estimated_target", "real_target"]
