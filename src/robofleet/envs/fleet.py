"""The episode physics behind :mod:`robofleet.envs`: an avoidance scenario's robots as
single integrators driven by desired velocities, optionally through the B-UAVC safety
filter (:class:`~robofleet.avoidance.safety_filter.SafetyFilter`). Plain numpy, no
PettingZoo: the environment class wraps it.

One step (the avoidance family's noise model, ``robofleet.avoidance.simulation``):

1. every robot's position estimate is its TRUE position plus a draw from ``N(0, Σ_i)``,
   every obstacle's a draw from ``N(0, Σ_o)`` (one seeded generator per episode);
2. desired velocities are limited to ``v_max`` (the robots' physical limit, :func:`limited`:
   shortened along their direction, for every finite value however large) and, with
   ``safety="buavc"``, filtered against every robot's B-UAVC built from the estimates;
   robots that have arrived hold still (they stay in the world as parked robots);
3. the TRUE positions move by ``u Δt`` and are kept inside the workspace shrunk by
   ``r_s`` (the walls stop a robot; they are not counted as contacts);
4. contacts are judged on TRUE positions as in the family's metrics
   (:func:`~robofleet.core.metrics.pair_contacts`, :func:`~robofleet.core.metrics.obstacle_contacts`):
   robot pairs closer than ``2 r_s``, robots closer than ``r_s`` to an obstacle.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..avoidance.cell import Cells
from ..avoidance.obstacles import wall_planes
from ..avoidance.projection import project_onto_cells
from ..avoidance.safety_filter import (
    FilterResult,
    SafetyFilter,
    single_integrator_spec,
)
from ..avoidance.world import World
from ..avoidance.spec import Spec
from ..core.errors import ConfigError
from ..core.metrics import obstacle_contacts, pair_contacts

SAFETY_MODES = ("buavc", "none")


@dataclass(frozen=True)
class StepOutcome:
    """What one physics step produced, per robot (true positions after the move)."""

    contacts: np.ndarray
    filtered: np.ndarray
    estimate_in_cell: np.ndarray
    empty_cell: np.ndarray
    velocity: np.ndarray
    estimates: np.ndarray
    result: FilterResult | None = None


@dataclass(eq=False)
class Fleet:
    """The robots of one scenario, reset per episode from a seeded generator.

    Parameters
    ----------
    spec: a 2-D avoidance scenario of single-integrator robots.
    safety: ``"buavc"`` (desired velocities go through the safety filter) or ``"none"``.
    """

    spec: Spec
    safety: str = "buavc"
    safety_filter: SafetyFilter | None = field(init=False, default=None)
    world: World | None = field(init=False, default=None)

    def __post_init__(self):
        single_integrator_spec(self.spec)
        if self.safety not in SAFETY_MODES:
            raise ConfigError(f"safety: expected one of {list(SAFETY_MODES)}, received {self.safety!r}")
        if self.safety == "buavc":
            self.safety_filter = SafetyFilter.from_spec(self.spec)
        self.workspace = self.spec.workspace.build()
        self.walls = wall_cells(self.spec)
        self._bounds: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    # -- episode ----------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> None:
        """A new episode: the layout (random layouts drawn from ``rng``), robots at rest."""
        self.rng = rng
        self.world = World(self.spec, rng)
        self.n = self.world.n
        self.goals = self.world.goals[:, :2].copy()
        self.positions = self.world.starts[:, :2].copy()
        self.velocity = np.zeros((self.n, 2))
        self.arrived = np.zeros(self.n, bool)
        self.radius = float(self.spec.robots.radius)
        self.covs = self.safety_filter.covariances if self.safety_filter is not None else None
        self.sense()

    def sense(self) -> None:
        """Draw this step's estimates of the robots and the obstacles."""
        self.estimates = self.positions + self.world.position_noise(self.rng)
        self.obstacle_offsets = self.world.obstacle_shift(self.rng)

    def goal_distance(self) -> np.ndarray:
        """TRUE distance of every robot to its goal."""
        return np.linalg.norm(self.goals - self.positions, axis=1)

    # -- step -------------------------------------------------------------------------------
    def step(self, desired: np.ndarray) -> StepOutcome:
        """Filter (or not), move, judge contacts, then sense for the next step."""
        desired, too_fast = limited(np.where(self.arrived[:, None], 0.0, desired), self.world.v_max)
        result = None
        if self.safety_filter is None:
            velocity = desired
            filtered, inside, empty = np.zeros(self.n, bool), np.ones(self.n, bool), np.zeros(self.n, bool)
        else:
            result = self.safety_filter.filter(self.estimates, self.covs, desired, self.obstacle_offsets)
            velocity = np.where(self.arrived[:, None], 0.0, result.velocity)
            filtered, inside, empty = (result.modified | too_fast) & ~self.arrived, result.estimate_in_cell, result.empty
        self.positions = self.keep_inside(self.positions + velocity * self.spec.dt)
        self.velocity = velocity
        contacts, used = self.contacts(), self.estimates
        self.sense()
        return StepOutcome(contacts, filtered, inside, empty, velocity, used, result)

    def keep_inside(self, positions: np.ndarray) -> np.ndarray:
        """Positions projected onto the workspace shrunk by ``r_s`` (the walls stop robots)."""
        out = np.flatnonzero(np.any(positions @ self.walls.A.T > self.walls.b, axis=1))
        if len(out) == 0:
            return positions
        proj = project_onto_cells(positions[out], self.walls.broadcast(len(out)))
        inside = positions.copy()
        inside[out] = np.where(proj.empty[:, None], positions[out], proj.point)
        return inside

    def contacts(self) -> np.ndarray:
        """Contacts per robot at the current TRUE positions (pairs count for both robots)."""
        count = np.zeros(self.n, np.int64)
        pairs = pair_contacts(self.positions[None], self.radius)[0]
        np.add.at(count, pairs[:, 1:].ravel(), 1)
        hits = obstacle_contacts(self.positions[None], self.radius, self.workspace)[0]
        np.add.at(count, hits[:, 1], 1)
        return count

    # -- observations -----------------------------------------------------------------------
    def neighbours(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` nearest other robots (∞-norm of the estimates, as the cells' local box)
        inside ``R_loc`` of each robot: ``(index (n, k), present (n, k))``."""
        if k == 0 or self.n < 2:
            return np.zeros((self.n, k), np.intp), np.zeros((self.n, k), bool)
        kk = min(k + 1, self.n)
        _, idx = cKDTree(self.estimates).query(self.estimates, k=kk, p=np.inf, distance_upper_bound=self.spec.local_box * (1 + 1e-12))
        idx = np.asarray(idx).reshape(self.n, kk)
        own_last = np.argsort(idx == np.arange(self.n)[:, None], axis=1, kind="stable")  # drop the robot itself
        index = np.full((self.n, k), self.n, np.intp)
        index[:, : kk - 1] = np.take_along_axis(idx, own_last, axis=1)[:, : min(k, kk - 1)]
        present = index < self.n
        return np.where(present, index, 0), present

    def observations(self, k: int) -> np.ndarray:
        """``(n, 6 + 3k)`` float32 rows: own estimate, own last velocity, goal − estimate,
        then per neighbour slot its estimate relative to the robot's and a presence flag
        (clipped to :meth:`observation_bounds`, which only a > 6σ error can reach)."""
        index, present = self.neighbours(k)
        relative = np.where(present[..., None], self.estimates[index] - self.estimates[:, None], 0.0)
        slots = np.concatenate([relative, present[..., None].astype(float)], axis=2).reshape(self.n, 3 * k)
        own = np.concatenate([self.estimates, self.velocity, self.goals - self.estimates], axis=1)
        if k not in self._bounds:
            self._bounds[k] = self.observation_bounds(k)
        low, high = self._bounds[k]
        return np.clip(np.concatenate([own, slots], axis=1), low, high).astype(np.float32)

    def observation_bounds(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds ``(6 + 3k,)`` of an observation: the workspace's extent
        widened by ``1 m + 6σ`` for estimates, ``±v_max`` for velocities, ``±R_loc`` and 0/1
        for the neighbour slots."""
        x0, y0, x1, y1 = self.workspace.extent
        margin = 1.0 + 6.0 * max(t.largest_sigma() for t in self.spec.team_specs())
        lo, hi = np.array([x0, y0]) - margin, np.array([x1, y1]) + margin
        v = max(t.v_max for t in self.spec.team_specs())
        reach, box = hi - lo, self.spec.local_box
        low = np.concatenate([lo, [-v, -v], -reach, np.tile([-box, -box, 0.0], k)])
        high = np.concatenate([hi, [v, v], reach, np.tile([box, box, 1.0], k)])
        return low, high


def limited(desired: np.ndarray, v_max: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(u · min(1, v_max / ‖u‖), ‖u‖ > v_max)`` per row: the speed limit, which keeps the
    direction of any finite ``u``. A row whose largest component exceeds ``v_max`` is first
    divided by that component and multiplied by ``v_max`` (the same direction, components
    at most ``v_max``), so no square overflows even for components near the largest float."""
    largest = np.abs(desired).max(axis=1, initial=0.0)
    over = largest > v_max
    u = desired.astype(float, copy=True)
    u[over] *= (v_max[over] / largest[over])[:, None]
    speed = np.hypot(u[:, 0], u[:, 1])
    too_fast = over | (speed > v_max)
    u[too_fast] *= (v_max[too_fast] / speed[too_fast])[:, None]
    return u, too_fast


@dataclass(frozen=True)
class WallCells:
    """The workspace walls tightened by ``r_s`` as one cell, broadcast to any fleet size."""

    A: np.ndarray
    b: np.ndarray

    def broadcast(self, n: int) -> Cells:
        m = len(self.b)
        return Cells(np.broadcast_to(self.A, (n, m, 2)), np.broadcast_to(self.b, (n, m)), np.ones((n, m), bool),
                     np.zeros((n, m), np.int8), np.zeros((n, m), np.intp))


def wall_cells(spec: Spec) -> WallCells:
    """Half-planes ``a·p ≤ b − r_s`` of the workspace bounds (convex by validation)."""
    a, b = wall_planes(spec.workspace.bounds_vertices())
    return WallCells(a, b - spec.robots.radius)
