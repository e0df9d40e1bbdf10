"""Six asynchronous followers form a wedge behind a turning leader (the flocking family).

Followers are oblivious, anonymous and see the others only in their own local frames
(Gervasi & Prencipe 2001, docs/theory/flocking.md). The run reports Δ_e, the 𝒟-distance
of the followers to the pattern placed where they estimate it, and whether it fell below ξ
and stayed there.

Run:  python examples/flocking_wedge.py [--duration 500] [--seed 0]
"""

from __future__ import annotations

import argparse

import robofleet


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=500.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    spec = robofleet.load_scenario("flocking/wedge_async", overrides={"duration": args.duration})
    trace = robofleet.simulate(spec, seed=args.seed)
    summary = trace.summary()
    print(f"{summary['n_followers']} followers, {summary['cycles']} Look-Compute-Move cycles, ξ = {summary['xi']:.1f}")
    since = summary["convergence_time_e"]
    held = f"below ξ from t = {since:.0f} on" if summary["converged_e"] else "not yet below ξ for good"
    print(f"Δ_e at the end {summary['delta_e_final']:.1f}, {held}; success: {summary['success']}")


if __name__ == "__main__":
    main()
