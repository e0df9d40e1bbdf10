"""RU: random choices with unvisited vertices first (Baranzadeh 2013, ref. [7] of Yang 2017).

Section 5: "random choices with unvisited vertices first (RU) in [7]. RU did not consider
collisions between robots. So, an additional move time is added for each collision."
Robots are points: they exchange maps with their communication neighbours (step 3), sense
obstacles, and all choose *simultaneously* by rule (1) from their own maps, ignoring the
other robots. Collisions (two robots on one vertex, or swapping along one edge) are allowed;
the simulator counts them and charges ``collision_penalty_moves`` move times for each.
"""

from __future__ import annotations

import numpy as np

from .policy import StepContext
from .step_kernels import random_unvisited_choices


class RandomUnvisitedPolicy:
    """Rule (1) for every active robot at once, without collision avoidance."""

    communicates = True
    collision_free = False

    def choose(self, ctx: StepContext) -> tuple[np.ndarray, np.ndarray]:
        """Rule (1) from every active robot's own map (:func:`.step_kernels.random_unvisited_choices`)."""
        grid, maps = ctx.grid, ctx.maps
        words, masks = grid.candidate_words
        choice = ctx.pos.copy()
        random_unvisited_choices(np.flatnonzero(ctx.active), ctx.pos, grid.candidates, words, masks,
                                 ctx.sensing.edge_sensed_ok, maps.layers, maps.touched, maps.dirty, maps.unchecked,
                                 ctx.streams.uniforms(), choice)
        return choice, np.ones(len(ctx.pos) // ctx.n, dtype=np.intp)
