"""The one loop: spec -> starts -> consensus steps -> Trace, written through the core recorder."""

from __future__ import annotations

from robofleet.core.recorder import Recorder
from robofleet.core.rng import keyed_generator, resolve_seed
from robofleet.core.trace import Trace

from .consensus import consensus_step
from .metrics import diameter, run_results
from .spec import Spec


def simulate(spec: Spec, seed: int | None = None, progress: bool = False) -> Trace:
    """Run a rendezvous scenario; ``seed=None`` draws a seed and records it (the seed rule)."""
    seed = resolve_seed(seed)
    robots = spec.robots
    starts = keyed_generator(seed, "starts").uniform(0.0, robots.area, size=(robots.n, 2))
    rec = Recorder(spec.max_steps, robots.n, label="rendezvous", progress=progress)
    rec.state("positions", (robots.n, 2), initial=starts)

    def step(k: int) -> bool:
        with rec.timed(k):
            after = consensus_step(rec["positions"][k], robots.sensing_range, robots.gain)
        rec.put_state(k + 1, positions=after)
        return diameter(after) <= spec.tolerance  # stop early once gathered

    rec.run(step)
    results = run_results(rec.arrays()["positions"], robots.sensing_range, spec.tolerance)
    return rec.trace("rendezvous", scenario=spec.scenario_name, seed=seed,
                     metadata={"sensing_range": robots.sensing_range, "gain": robots.gain}, results=results)
