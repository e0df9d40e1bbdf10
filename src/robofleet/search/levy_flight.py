"""LFP: Lévy flight with an artificial potential field (Sutantyo et al. 2010, ref. [12]),
adapted to the grid.

The original is continuous: a robot draws a step length from a Lévy distribution
(Mantegna's algorithm, exponent β ≈ 1.5) and a turning angle from a normal distribution,
and the repulsive force of nearby robots, borders and obstacles bends its path. Robots do
not communicate, so they keep no shared map (Section 1 of Yang 2017).

Grid adaptation (a documented choice; Yang 2017 compares the methods on one area and one
sensing model):

* a *flight* has a heading ``θ`` and a length of ``L`` edges, ``L = ⌈|s|⌉`` with
  ``s = σ_u z₀ / |z₁|^{1/β}`` (Mantegna), ``σ_u = [Γ(1+β) sin(πβ/2) / (Γ((1+β)/2) β
  2^{(β−1)/2})]^{1/β}``, clipped to ``[1, max_flight]``; a new flight turns by
  ``θ ← θ + σ_turn z₂``;
* every step the robot moves to the free neighbour vertex whose direction is closest to
  ``d = (cos θ, sin θ) + w Σ_j (p_i − p_j)/‖p_i − p_j‖² + w Σ_blocked (−e_k)/a`` — the sum over
  robots it senses within ``r_so`` and over the edges it senses blocked (the potential field);
* vertices occupied by sensed robots are not options, but choices are simultaneous and
  uncoordinated, so two robots can pick one vertex: a collision, counted and charged like RU;
* when no free neighbour lies within 90° of ``d`` the robot slides along the best free edge
  and takes that edge's direction as its new heading; with no free neighbour it stays and
  ends the flight.
"""

from __future__ import annotations

import math

import numpy as np

from .policy import StepContext
from .step_kernels import levy_choices


def mantegna_sigma(beta: float) -> float:
    """``σ_u`` of Mantegna's algorithm for Lévy-stable step lengths with exponent ``beta``."""
    num = math.gamma(1 + beta) * math.sin(math.pi * beta / 2)
    den = math.gamma((1 + beta) / 2) * beta * 2 ** ((beta - 1) / 2)
    return (num / den) ** (1 / beta)


class LevyFlightPolicy:
    """Simultaneous Lévy-flight moves with repulsion, no communication."""

    communicates = False
    collision_free = False

    def __init__(self, n_robots: int, *, beta: float, turn_sigma: float, repulsion: float, max_flight: int, r_so: float):
        self.beta, self.turn_sigma, self.repulsion, self.max_flight, self.r_so = beta, turn_sigma, repulsion, max_flight, r_so
        self.sigma_u = mantegna_sigma(beta)
        self.heading = np.zeros(n_robots)
        self.remaining = np.zeros(n_robots, dtype=np.intp)
        self.started = False

    def flight_lengths(self, z: np.ndarray) -> np.ndarray:
        """Flight lengths ``L = ⌈|s|⌉`` clipped to ``[1, max_flight]`` (Mantegna's ``s``) of the
        normal draws ``z (..., 3)`` (``z₀``, ``z₁``), as edge counts of ``z``'s shape but the last."""
        step = self.sigma_u * z[..., 0] / np.maximum(np.abs(z[..., 1]), 1e-12) ** (1 / self.beta)
        return np.minimum(np.maximum(np.ceil(np.abs(step)), 1), self.max_flight).astype(np.intp)

    def new_flights(self, robots: np.ndarray, z: np.ndarray, u: np.ndarray, first: bool) -> None:
        """Draw length and turn for ``robots``; a robot's first flight takes a uniform heading."""
        zr = z[robots]
        self.remaining[robots] = self.flight_lengths(zr)
        if first:
            self.heading[robots] = 2 * np.pi * u[robots]
        else:
            self.heading[robots] += self.turn_sigma * zr[:, 2]

    def choose(self, ctx: StepContext) -> tuple[np.ndarray, np.ndarray]:
        """One grid move of every active robot (:func:`.step_kernels.levy_choices`); a robot
        whose flight is spent first draws a new one."""
        z, u = ctx.streams.normals(), ctx.streams.uniforms()
        robots = np.flatnonzero(ctx.active) if not ctx.active.all() else np.arange(len(ctx.pos))
        first = not self.started
        self.started = True
        ending = robots if first else robots[self.remaining[robots] <= 0]
        if len(ending):
            self.new_flights(ending, z, u, first)
        grid, nb = ctx.grid, ctx.neighbours
        words, masks = grid.candidate_words
        heading = self.heading[robots]
        choice = ctx.pos.copy()
        slot, slide = levy_choices(robots, ctx.pos, grid.candidates, words, masks, ctx.sensing.edge_sensed_ok,
                                   ctx.maps.layers, nb.start, nb.peer, nb.sensed, bool(nb.sensed.any()), grid.points,
                                   grid.edge_units, ctx.sensing.wall_push, np.cos(heading), np.sin(heading),
                                   float(self.repulsion), self.remaining, choice)
        if slide.any():
            step_vec = grid.edge_units[ctx.pos[robots[slide]], slot[slide]]
            self.heading[robots[slide]] = np.arctan2(step_vec[:, 1], step_vec[:, 0])
        return choice, np.ones(len(ctx.pos) // ctx.n, dtype=np.intp)
