"""A toy scenario family for sweep tests: robots random-walking towards their goals.

It is registered under the name ``toy`` by the ``toy_family`` fixture (in-process only),
so the sweep machinery can be tested end to end independently of the paper families.
"""

from __future__ import annotations

import time
from typing import Literal

import numpy as np
from pydantic import Field

from robofleet.core.rng import as_generator
from robofleet.core.trace import Trace
from robofleet.scenarios import SpecModel


class Robots(SpecModel):
    n: int = Field(2, gt=0, le=50)
    radius: float = Field(0.1, gt=0)


class Noise(SpecModel):
    sigma: float = Field(0.0, ge=0)


class Spec(SpecModel):
    family: Literal["toy"] = "toy"
    robots: Robots = Robots()
    noise: Noise = Noise()
    steps: int = Field(20, gt=0)


def simulate(spec: Spec, seed=None, progress: bool = False) -> Trace:
    """Each robot moves a tenth of the way to its goal per step, plus Gaussian noise."""
    rng = as_generator(seed)
    n = spec.robots.n
    angles = 2 * np.pi * np.arange(n) / n
    starts = np.stack([np.cos(angles), np.sin(angles)], axis=1) * n
    goals = starts + np.array([0.0, 5.0])
    positions = [starts]
    seconds = []
    for _ in range(spec.steps):
        t0 = time.perf_counter()
        p = positions[-1]
        positions.append(p + 0.3 * (goals - p) + spec.noise.sigma * rng.standard_normal(p.shape))
        seconds.append(time.perf_counter() - t0)
    arrays = {"positions": np.stack(positions), "step_seconds": np.asarray(seconds)}
    metadata = {"dt": 0.1, "radius": spec.robots.radius, "goals": goals.tolist(), "goal_tolerance": 0.05}
    return Trace("toy", arrays, [], metadata, {"final_spread": float(np.ptp(positions[-1][:, 0]))})
