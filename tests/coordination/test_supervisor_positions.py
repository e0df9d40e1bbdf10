"""Position reports (the supervisor's *Position reports* claim), adversarially: random
plans that back up over themselves, return to the very points they left, wait and take
steps shorter than the tolerance; errors uniform in the tolerance disc, on its rim, and
pointing to later steps of the plan; robots between steps, holding still now and then,
answers late and lost. Known progress never passes the true progress, no two robots
are ever in collision, and every run finishes."""

from __future__ import annotations

import numpy as np
import pytest
from supervisor_loops import executor_for, position_loop, wandering_instance

TOLERANCE = 0.2
LOOKAHEADS = (1, 3, 10, None)


@pytest.mark.parametrize("method", ["rmtrack", "tff", "tfa"])
def test_position_reports_never_overestimate_progress_nor_collide_nor_stall(method):
    runs = []
    for seed in range(8):
        rng = np.random.default_rng([seed, len(method)])
        traj = wandering_instance(rng, 2 + seed % 3, TOLERANCE)
        result = position_loop(executor_for(traj, method), seed, TOLERANCE, LOOKAHEADS[seed % 4])
        runs.append((seed, result.overestimates, result.contacts, result.stalled))
    assert [r for r in runs if any(r[1:])] == []
