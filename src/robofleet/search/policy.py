"""Shared pieces of the choice policies: the per-step context, per-robot random streams and
the uniform pick among options.

A policy has ``communicates`` (whether step 3 map exchange happens), ``collision_free``
(whether it claims the invariants of Section 4) and ``choose(ctx) -> (choices, rounds)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.rng import keyed_generator
from .grids import Grid
from .knowledge import RobotMaps
from .sensing import SensingTables


class RobotStreams:
    """One independent random stream per robot (its own generator, keyed by seed and label).

    A robot's draws never depend on what other robots drew, so the outcome does not depend
    on the order in which the simulator evaluates robots, nor on which other runs share a
    batch. Draws are buffered in chunks.
    """

    def __init__(self, seeds: list[int], n_robots: int, chunk: int = 256):
        self.generators = [keyed_generator(seed, "search-robot", i) for seed in seeds for i in range(n_robots)]
        self.chunk = chunk
        self._uniform = np.empty((n_robots, 0))
        self._normal = np.empty((n_robots, 0, 3))
        self._u = self._z = 0

    def uniforms(self) -> np.ndarray:
        """Next ``U[0, 1)`` draw of every robot, ``(n,)``."""
        if self._u >= self._uniform.shape[1]:
            self._uniform = np.stack([g.random(self.chunk) for g in self.generators]) if self.generators else np.empty((0, self.chunk))
            self._u = 0
        self._u += 1
        return self._uniform[:, self._u - 1]

    def normals(self) -> np.ndarray:
        """Next three standard normal draws of every robot, ``(n, 3)``."""
        if self._z >= self._normal.shape[1]:
            self._normal = np.stack([g.standard_normal((self.chunk, 3)) for g in self.generators]) if self.generators else np.empty((0, self.chunk, 3))
            self._z = 0
        self._z += 1
        return self._normal[:, self._z - 1]


@dataclass
class StepContext:
    """What the robots can use at step ``k``, for a batch of ``R`` independent runs of ``n``
    robots each (robot ``g`` is robot ``g % n`` of run ``g // n``; runs never interact).

    ``pos (R·n,)`` vertex ids; ``active (R·n,)`` alive robots of unfinished runs;
    ``links (R, n, n)`` communication neighbours (alive, within ``r_c``); ``sensed (R, n, n)``
    robots within ``r_so`` (failed ones included); ``aware = links | sensed``; ``maps`` the
    per-robot knowledge. Use :meth:`rows` / :meth:`peers` to read what a robot knows about
    the robots of its own run.
    """

    grid: Grid
    sensing: SensingTables
    maps: RobotMaps
    streams: RobotStreams
    pos: np.ndarray
    heading: np.ndarray
    active: np.ndarray
    links: np.ndarray
    sensed: np.ndarray
    aware: np.ndarray

    @property
    def n(self) -> int:
        """Robots per run."""
        return self.links.shape[-1]

    def rows(self, relation: np.ndarray, robots: np.ndarray) -> np.ndarray:
        """``(m, n)``: the rows of ``robots`` in a per-run relation ``(R, n, n)``."""
        return relation[robots // self.n, robots % self.n]

    def peers(self, values: np.ndarray, robots: np.ndarray) -> np.ndarray:
        """``(m, n, ...)``: ``values (R·n, ...)`` of the robots in the run of each of ``robots``."""
        return values.reshape(-1, self.n, *values.shape[1:])[robots // self.n]

    def peer_ids(self, robots: np.ndarray, local: np.ndarray) -> np.ndarray:
        """Global ids of robot ``local`` of the run of each of ``robots``."""
        return (robots // self.n) * self.n + local


def pick_uniform(cand: np.ndarray, pool: np.ndarray, u: np.ndarray, stay: np.ndarray) -> np.ndarray:
    """For each row, the option of ``pool`` with index ``⌊u · |pool|⌋``; ``stay`` if empty.

    This is a uniform choice "with prob. ``1/|V|``" of rules (1) and (2).
    """
    count = pool.sum(axis=1)
    index = np.minimum((u * count).astype(np.intp), np.maximum(count - 1, 0))
    slot = np.argmax(np.cumsum(pool, axis=1) > index[:, None], axis=1)
    return np.where(count > 0, cand[np.arange(len(cand)), slot], stay)
