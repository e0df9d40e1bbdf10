"""How often the premise of the B-UAVC guarantee holds on the shipped avoidance scenarios.

The per-step chance constraint of Zhu et al. 2022 (Sec. 4) bounds the collision
probability of a pair by δ when both robots' estimates lie in their own cells. This
script runs every shipped ``scenarios/avoidance/*.yaml`` for ``--seeds`` seeds (0, 1, ...)
under each ``--methods`` and prints, per scenario and method:

* ``in cell``: the share of robot-steps of robots not yet arrived whose estimate lay in
  its own cell (``estimate_in_cell_share``, pooled over the seeds' robot-steps);
* ``empty``: the share of those robot-steps whose cell was empty (``empty_cell_share``);
* ``close``: the (pair, step) couples with centres under 1 m, the contacts among them,
  their rate (``close_pair_step_rate``, pooled) with its Clopper–Pearson 95 % upper
  bound, next to δ and the pooled ``pair_step_rate`` over all couples.

Run: ``python benchmarks/avoidance_premise.py [--seeds 20] [--methods buavc bvc] [--scenarios three_boxes ...]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.stats import beta

import robofleet
from robofleet.avoidance.simulation import simulate

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios" / "avoidance"


def clopper_pearson_upper(hits: int, trials: int, level: float = 0.95) -> float:
    """Upper end of the two-sided ``level`` Clopper–Pearson interval for ``hits`` of ``trials``."""
    if trials == 0:
        return float("nan")
    return 1.0 if hits == trials else float(beta.ppf(1 - (1 - level) / 2, hits + 1, trials - hits))


def pooled(path: Path, method: str, seeds: int) -> dict:
    """Premise shares and close-pair contacts of ``seeds`` runs, pooled over robot-steps and couples."""
    data = robofleet.load_scenario(path).model_dump(exclude={"source"})
    data["method"] = method
    spec = robofleet.load_scenario(data)
    moving = inside = empty = close = close_hits = pair_steps = pair_hits = successes = 0
    for seed in range(seeds):
        trace = simulate(spec, seed=seed)
        a, r = trace.arrays, trace.results
        steps = len(a["estimate_in_cell"])
        alive = moving_mask(steps, a["arrival_steps"])
        moving += int(alive.sum())
        inside += int(a["estimate_in_cell"][alive].sum())
        empty += int(a["empty_cell"][alive].sum())
        close += r["close_pair_steps"]
        close_hits += round(r["close_pair_step_rate"] * r["close_pair_steps"]) if r["close_pair_steps"] else 0
        n = a["positions"].shape[1]
        couples = n * (n - 1) // 2 * len(a["positions"])
        pair_steps += couples
        pair_hits += round(r["pair_step_rate"] * couples)
        successes += bool(r["success"])
    return {"in_cell": inside / moving, "empty": empty / moving, "close": close, "close_hits": close_hits,
            "close_rate": close_hits / close if close else float("nan"), "close_upper": clopper_pearson_upper(close_hits, close),
            "pair_rate": pair_hits / pair_steps, "delta": spec.delta, "success": successes / seeds}


def moving_mask(steps: int, arrivals: np.ndarray) -> np.ndarray:
    """Robot-steps ``(k, i)`` with ``k`` before robot i's arrival step (every step if it never arrived)."""
    k = np.arange(steps)[:, None]
    return (arrivals[None, :] < 0) | (k < arrivals[None, :])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--methods", nargs="+", default=["buavc", "bvc"])
    parser.add_argument("--scenarios", nargs="+", default=None, help="file stems (default: every shipped avoidance scenario)")
    args = parser.parse_args()
    paths = sorted(SCENARIOS.glob("*.yaml")) if args.scenarios is None else [SCENARIOS / f"{s}.yaml" for s in args.scenarios]
    print(f"{args.seeds} seeds (0..{args.seeds - 1}) per scenario and method; shares pooled over robot-steps of robots not yet arrived")
    print("| scenario | method | success | estimate in cell | empty cell | close pair-steps | contacts | close rate (95 % upper) | δ | pooled pair_step_rate |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for path in paths:
        for method in args.methods:
            p = pooled(path, method, args.seeds)
            print(f"| `{path.name}` | {method} | {p['success']:.0%} | {p['in_cell']:.1%} | {p['empty']:.2%} | {p['close']} | {p['close_hits']} | "
                  f"{p['close_rate']:.2e} ({p['close_upper']:.1e}) | {p['delta']} | {p['pair_rate']:.1e} |", flush=True)


if __name__ == "__main__":
    main()
