"""Shared pieces of the choice policies: the per-step context and per-robot random streams.

A policy has ``communicates`` (whether step 3 map exchange happens), ``collision_free``
(whether it claims the invariants of Section 4) and ``choose(ctx) -> (choices, rounds)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.rng import keyed_generator
from .grids import Grid
from .knowledge import RobotMaps
from .neighbours import Neighbours, from_dense
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

    def uniform_block(self) -> np.ndarray:
        """The next ``chunk`` ``U[0, 1)`` draws of every robot, ``(n, chunk)``."""
        return np.stack([g.random(self.chunk) for g in self.generators]) if self.generators else np.empty((0, self.chunk))

    def normal_block(self) -> np.ndarray:
        """The next ``chunk`` triples of standard normal draws of every robot, ``(n, chunk, 3)``."""
        return np.stack([g.standard_normal((self.chunk, 3)) for g in self.generators]) if self.generators else np.empty((0, self.chunk, 3))

    def uniforms(self) -> np.ndarray:
        """Next ``U[0, 1)`` draw of every robot, ``(n,)`` (a column of :meth:`uniform_block`)."""
        if self._u >= self._uniform.shape[1]:
            self._uniform = self.uniform_block()
            self._u = 0
        self._u += 1
        return self._uniform[:, self._u - 1]

    def normals(self) -> np.ndarray:
        """Next three standard normal draws of every robot, ``(n, 3)`` (a row of :meth:`normal_block`)."""
        if self._z >= self._normal.shape[1]:
            self._normal = self.normal_block()
            self._z = 0
        self._z += 1
        return self._normal[:, self._z - 1]


@dataclass
class StepContext:
    """What the robots can use at step ``k``, for a batch of ``R`` independent runs of ``n``
    robots each (robot ``g`` is robot ``g % n`` of run ``g // n``; runs never interact).

    ``pos (R·n,)`` vertex ids; ``active (R·n,)`` alive robots of unfinished runs; ``maps``
    the per-robot knowledge; ``neighbours`` the sparse relation of
    :class:`~.neighbours.Neighbours`: communication neighbours (``link``: alive, within
    ``r_c``) and robots within ``r_so`` (``sensed``, failed ones included). A context can
    also be given the relation as dense ``(R, n, n)`` matrices ``links``, ``sensed`` and
    ``aware = links | sensed`` (hand-built contexts); the policies read ``neighbours`` only.
    """

    grid: Grid
    sensing: SensingTables
    maps: RobotMaps
    streams: RobotStreams
    pos: np.ndarray
    heading: np.ndarray
    active: np.ndarray
    links: np.ndarray | None = None
    sensed: np.ndarray | None = None
    aware: np.ndarray | None = None
    neighbours: Neighbours | None = None

    def __post_init__(self) -> None:
        if self.neighbours is None:
            self.neighbours = from_dense(self.links, self.sensed)

    @property
    def n(self) -> int:
        """Robots per run."""
        return self.neighbours.n
