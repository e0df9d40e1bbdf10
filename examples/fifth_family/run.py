"""Register the example family, pass the conformance checker, and run it like any other.

In the repository a fifth family is one more import in ``robofleet/scenarios/registry.py``
(docs/fifth-family.md); an out-of-tree package, as here, adds its ``FAMILY`` to the family
table before loading its scenarios.

Run:  python examples/fifth_family/run.py [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # the example package `rendezvous` lives beside this file

import robofleet  # noqa: E402
from robofleet.scenarios import FAMILIES  # noqa: E402
from robofleet.testing import check_scenario  # noqa: E402
from rendezvous import FAMILY  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    FAMILIES.setdefault(FAMILY.name, FAMILY)
    check_scenario(HERE / "gather.yaml", steps=5)  # raises ConformanceError listing every failure
    print("conformance: passed")
    spec = robofleet.load_scenario(HERE / "gather.yaml")
    for guarantee in FAMILY.check(spec):
        print(guarantee.line())
    summary = robofleet.simulate(spec, seed=args.seed).summary()
    print(f"diameter {summary['initial_diameter']:.2f} m -> {summary['final_diameter']:.3f} m in {summary['n_steps']} steps; "
          f"gathered: {summary['success']}, groups: {summary['components']}, hull growth {summary['hull_growth']:.1e} m²")


if __name__ == "__main__":
    main()
