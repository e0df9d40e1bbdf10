"""Decentralized grid search of an unknown area with one robot failing on the way (the
search family).

Robots move one grid edge per step, choose in a fixed order so that no two pick one
vertex, and share their maps with the robots in communication range (Yang 2017,
docs/theory/search.md). Robot 1 stops moving and answering at step 6; its neighbours
notice the missing replies, treat its vertex as blocked, and the others still search the
whole area (situation 2: stop when no unvisited vertex is left).

Run:  python examples/search_with_failure.py [--seed 0]
"""

from __future__ import annotations

import argparse

import robofleet


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    spec = robofleet.load_scenario("search/failure_injection")
    summary = robofleet.simulate(spec, seed=args.seed).summary()
    print(f"{summary['n_robots']} robots, {summary['failed_robots']} failed; search completed: {summary['completed']} "
          f"after {summary['search_time']:.0f} s, {summary['detected_share']:.1%} of the area sensed, "
          f"collisions {summary['collisions']}")


if __name__ == "__main__":
    main()
