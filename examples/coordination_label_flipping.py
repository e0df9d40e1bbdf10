"""RMTRACK with and without label flipping on one plan and one set of delays (the
coordination family).

The five-robot X-corridor scenario is executed three times with the same seed, hence the
same plan and the same disturbances: plain RMTRACK (Eq. 1), RMTRACK+TFF with the
segment-graph deadlock check, and RMTRACK+TFA with it (docs/theory/coordination.md).
`robofleet check` states first which of the paper's conditions the plan meets.

Run:  python examples/coordination_label_flipping.py [--seed 1]
"""

from __future__ import annotations

import argparse

import robofleet
from robofleet.scenarios import family_of


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    spec = robofleet.load_scenario("coordination/x_corridor_5_tff")
    for guarantee in family_of(spec).check(spec):
        print(guarantee.line())
    for method in ("rmtrack", "tff", "tfa"):
        variant = robofleet.load_scenario("coordination/x_corridor_5_tff", overrides={"policy.method": method})
        summary = robofleet.simulate(variant, seed=args.seed).summary()
        print(f"{summary['variant']:22s} finished: {summary['finished']}, deadlock: {summary['deadlock']}, "
              f"mean travel time {summary['mean_travel_time']:.1f} s, flips {summary['flips']}, collisions {summary['collisions']}")


if __name__ == "__main__":
    main()
