"""A toy scenario family, filling in the family contract the way a fifth paper would.

Robots move a fraction of the way to their goals each step, plus Gaussian noise. It is
registered under the name ``toy`` by the ``toy_family`` fixture (in-process and forked
workers only), so the sweep machinery, the CLI and the conformance checker can be tested
end to end independently of the paper families.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from robofleet.core.config import SpecModel
from robofleet.core.family import Family, Guarantee
from robofleet.core.metrics import MOTION_RESULTS, motion_summary
from robofleet.core.recorder import Recorder
from robofleet.core.rng import as_generator, resolve_seed
from robofleet.core.trace import Trace


class Robots(SpecModel):
    n: int = Field(2, gt=0, le=50)
    radius: float = Field(0.1, gt=0)


class Noise(SpecModel):
    sigma: float = Field(0.0, ge=0)


class Spec(SpecModel):
    family: Literal["toy"] = "toy"
    name: str = ""
    robots: Robots = Robots()
    noise: Noise = Noise()
    steps: int = Field(20, gt=0)


def simulate(spec: Spec, seed: int | None = None, progress: bool = False) -> Trace:
    """Each robot moves 30 % of the way to its goal per step, plus Gaussian noise."""
    seed = resolve_seed(seed)
    rng = as_generator(seed)
    n = spec.robots.n
    angles = 2 * np.pi * np.arange(n) / n
    starts = np.stack([np.cos(angles), np.sin(angles)], axis=1) * n
    goals = starts + np.array([0.0, 5.0])
    rec = Recorder(spec.steps, n, label="toy", progress=progress)
    rec.state("positions", (n, 2), initial=starts)

    def step(k: int) -> bool:
        with rec.timed(k):
            p = rec["positions"][k]
            rec.put_state(k + 1, positions=p + 0.3 * (goals - p) + spec.noise.sigma * rng.standard_normal(p.shape))
        rec.arrive(k + 1, np.linalg.norm(rec["positions"][k + 1] - goals, axis=1) < 0.05)
        return False

    rec.run(step)
    trace = rec.trace("toy", scenario=spec.scenario_name, seed=seed, metadata={"dt": 0.1, "radius": spec.robots.radius, "goals": goals.tolist()})
    motion = motion_summary(trace.positions, goals, spec.robots.radius, 0.1, 0.05, None,
                            trace.arrays["step_seconds"], trace.arrays["arrival_steps"])
    trace.results.update(motion, final_spread=float(np.ptp(trace.positions[-1][:, 0])))
    return trace


def check(spec: Spec) -> list[Guarantee]:
    """The toy's one checkable condition: noise-free robots converge to their goals."""
    quiet = spec.noise.sigma == 0
    return [Guarantee("noise-free convergence", "toy model", quiet, f"sigma = {spec.noise.sigma}", "every robot reaches its goal")]


FAMILY = Family(name="toy", title="toy random walk", paper="nobody 2026", spec=Spec, simulate=simulate, check=check,
                viz="robofleet.viz.no_such_module", budget="steps", results={**MOTION_RESULTS, "final_spread": "x-extent of the final positions"})
