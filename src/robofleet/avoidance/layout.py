"""Starts and goals of an avoidance scenario: the deterministic layouts of the spec
(:func:`~.spec.deterministic_layout`) and the sampled ``antipodal`` layouts, drawn from
the run's generator (the authors' random antipodal swap, docs/theory/buavc.md "Setups")."""

from __future__ import annotations

import numpy as np

from ..core.errors import ScenarioError
from .spec import Spec, TeamSpec, deterministic_layout, start_clearances


def sample_antipodal(spec: Spec, team: TeamSpec, rng: np.random.Generator, max_tries: int = 10_000) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals of an ``antipodal`` layout, sampled as in the authors' setup
    (robot i at a random angle within its own sector of width 2π/n, radius
    U(r_min, r_max), goal = −start), rejection-sampled robot by robot so that every start
    and goal keeps the clearances of :func:`start_clearances` from the others, the
    obstacles and the bounds.

    O(N log N) and the same draws as trying robot by robot: the tries of a run of robots
    are made at once (the workspace clearances of all their candidates in one call, the
    robot clearances against a :class:`~.neighbours.PointGrid` of the points placed so
    far); a refused try ends the run, the next run starts from that robot's next draw,
    and the generator is left exactly as far advanced as the tries used."""
    from .neighbours import PointGrid

    lay, n = team.layout, team.n
    robot_gap, obstacle_gap, wall_gap = start_clearances(spec)
    ws = spec.workspace.build()
    center = np.asarray(lay.center, dtype=float)
    starts = np.zeros((n, 2))
    placed = PointGrid(2 * n, robot_gap)
    draws = _DrawAhead(rng)
    i, tries, run = 0, 0, 8
    while i < n:
        count = min(run, n - i)
        u = draws.peek(2 * count)
        s = _antipodal_offsets(np.arange(i, i + count), u[0::2], u[1::2], n, lay.r_min, lay.r_max)
        first, second = center + s, center - s
        both = np.concatenate([first, second])
        admissible = ((ws.boundary_distance(both) >= wall_gap) & (ws.obstacle_distance(both) >= obstacle_gap)).reshape(2, count).all(axis=0)
        accepted = placed.accept_run(first, second, admissible)
        starts[i : i + accepted] = s[:accepted]
        draws.consume(2 * min(accepted + 1, count))
        i, tries = (i + accepted, 0) if accepted else (i, tries)
        if accepted < count:
            tries += 1
            if tries >= max_tries:
                draws.settle()
                raise ScenarioError("robots.layout", f"room for robot {i} after {max_tries} tries (fewer robots or a larger ring)", n)
        run = min(2 * run, 4096) if accepted == count else 8
    draws.settle()
    return center + starts, center - starts


def _antipodal_offsets(robots: np.ndarray, u_angle: np.ndarray, u_radius: np.ndarray, n: int, r_min: float, r_max: float) -> np.ndarray:
    """``s_i = ρ (cos φ, sin φ)`` with ``φ = 2π(i + u)/n`` and ``ρ = r_min + (r_max − r_min) u'``
    (what ``rng.uniform(r_min, r_max)`` computes from its draw)."""
    ang = 2 * np.pi * (robots + u_angle) / n
    rad = r_min + (r_max - r_min) * u_radius
    return rad[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])


class _DrawAhead:
    """Uniform draws of ``rng`` read ahead in blocks; :meth:`settle` leaves ``rng``
    advanced by exactly the draws consumed (``rng.random()`` and ``rng.uniform()`` each
    take one double of the stream)."""

    def __init__(self, rng: np.random.Generator):
        self.rng, self.state = rng, rng.bit_generator.state
        self.buffer, self.used = np.empty(0), 0

    def peek(self, k: int) -> np.ndarray:
        if self.used + k > len(self.buffer):
            self.buffer = np.concatenate([self.buffer, self.rng.random(max(k, len(self.buffer)))])
        return self.buffer[self.used : self.used + k]

    def consume(self, k: int) -> None:
        self.used += k

    def settle(self) -> None:
        self.rng.bit_generator.state = self.state
        self.rng.random(self.used)


def initial_layout(spec: Spec, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, list[slice]]:
    """Starts and goals ``(N, d)`` of the whole fleet (random layouts drawn from ``rng``)
    and each team's slice."""
    teams = spec.team_specs()
    if len(teams) == 1 and teams[0].layout.kind == "antipodal":
        starts, goals = sample_antipodal(spec, teams[0], rng)
        return starts, goals, spec.team_slices()
    return deterministic_layout(spec)
