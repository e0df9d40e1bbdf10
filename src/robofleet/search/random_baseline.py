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

from .policy import StepContext, pick_uniform


class RandomUnvisitedPolicy:
    """Rule (1) for every active robot at once, without collision avoidance."""

    communicates = True
    collision_free = False

    def choose(self, ctx: StepContext) -> tuple[np.ndarray, np.ndarray]:
        robots = np.flatnonzero(ctx.active)
        here = ctx.pos[robots]
        cand = ctx.grid.candidates[here]
        words, masks = ctx.grid.candidate_words
        words, masks = words[here], masks[here]
        options = ctx.sensing.edge_sensed_ok[here] & ~ctx.maps.test_words(2, robots, words, masks)
        unvisited = options & ~ctx.maps.test_words(0, robots, words, masks)
        pool = np.where(unvisited.any(axis=1, keepdims=True), unvisited, options)
        u = ctx.streams.uniforms()
        choice = ctx.pos.copy()
        choice[robots] = pick_uniform(cand, pool, u[robots], here)
        ctx.maps.set(0, robots, choice[robots])
        return choice, np.ones(len(ctx.pos) // ctx.n, dtype=np.intp)
