"""The PettingZoo environment (``robofleet.envs``): speed and what the safety filter buys.

1. Environment steps per second of ``parallel_env(..., safety=buavc|none)`` at 10 and 100
   agents (the circle swap, spacing kept at ≈ 0.75 m), random actions drawn beforehand
   with numpy so that only the environment is timed (noise, filter, motion, contacts,
   observations, rewards and the dicts).
2. The random policy (``action_space(agent).sample()``, seeded) with and without the
   B-UAVC filter over many episodes: episodes with at least one contact (robot pairs
   closer than 2 r_s, robots closer than r_s to an obstacle, TRUE positions), contact
   steps, and the filter's premise share (estimate inside its own cell).

Prints figures; asserts nothing. Needs the ``rl`` extra.

Run:  nice python benchmarks/envs.py [--episodes 100] [--speed-steps 300] [--skip-evidence]
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

SPEED_SIZES = (10, 100)
EVIDENCE = (  # scenario, overrides, max_steps
    ("avoidance/circle_swap", {"robots.n": 32}, 200),
    ("avoidance/ten_boxes", None, 500),
)


def circle(n: int) -> dict:
    """The circle swap with ``n`` robots, the circle and workspace grown to keep ≈ 0.75 m spacing."""
    radius = max(4.0, n * 0.75 / (2 * np.pi))
    half = radius + 1.0
    return {"robots.n": n, "robots.layout.radius": radius, "workspace.bounds": [-half, -half, half, half]}


def steps_per_second(n: int, safety: str, steps: int) -> tuple[float, float]:
    from robofleet.envs import parallel_env

    env = parallel_env("avoidance/circle_swap", safety, overrides=circle(n), max_steps=steps + 1)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.4, 0.4, (steps + 5, n, 2))
    env.step({a: actions[0, i] for i, a in enumerate(env.agents)})  # warm-up (compiled kernels loaded)
    t0 = time.perf_counter()
    for k in range(1, steps + 1):
        env.step({a: actions[k, int(a[6:])] for a in env.agents})
    seconds = time.perf_counter() - t0
    return steps / seconds, 1e3 * seconds / steps


def random_policy(scenario: str, overrides: dict | None, max_steps: int, safety: str, episodes: int) -> dict:
    from robofleet.envs import parallel_env

    env = parallel_env(scenario, safety, overrides=overrides, max_steps=max_steps)
    collided = contact_steps = steps = 0
    inside = []
    for episode in range(episodes):
        env.reset(seed=episode)
        for k, agent in enumerate(env.agents):
            env.action_space(agent).seed(1000 * episode + k)
        while env.agents:
            _, _, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
            steps += 1
            inside += [info["estimate_in_cell"] for info in infos.values() if "estimate_in_cell" in info]
        collided += env.episode_contacts > 0
        contact_steps += env.episode_contacts
    return {"collided": collided, "contact_steps": contact_steps, "steps": steps,
            "inside": float(np.mean(inside)) if inside else float("nan"), "n": len(env.possible_agents)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=100, help="episodes per scenario and safety mode")
    ap.add_argument("--speed-steps", type=int, default=300, help="timed steps per size")
    ap.add_argument("--skip-evidence", action="store_true", help="only the speed table")
    args = ap.parse_args()
    print(f"numba threads: {numba.get_num_threads()}")
    print("\n## environment steps per second (circle swap, random actions)")
    print("| agents | safety | steps/s | ms per step | agent-steps/s |")
    print("|---:|---|---:|---:|---:|")
    for n in SPEED_SIZES:
        for safety in ("buavc", "none"):
            rate, ms = steps_per_second(n, safety, args.speed_steps)
            print(f"| {n} | {safety} | {rate:.0f} | {ms:.2f} | {rate * n:.0f} |", flush=True)
    if args.skip_evidence:
        return
    print(f"\n## random policy, {args.episodes} episodes per row (seeds 0–{args.episodes - 1})")
    print("| scenario | agents | max steps | safety | episodes with a contact | contact steps | estimate in own cell |")
    print("|---|---:|---:|---|---:|---:|---:|")
    for scenario, overrides, max_steps in EVIDENCE:
        for safety in ("none", "buavc"):
            r = random_policy(scenario, overrides, max_steps, safety, args.episodes)
            inside = "—" if safety == "none" else f"{r['inside']:.1%}"
            label = scenario + (f" {overrides}" if overrides else "")
            print(f"| `{label}` | {r['n']} | {max_steps} | {safety} | {r['collided']} / {args.episodes} | {r['contact_steps']} | {inside} |",
                  flush=True)


if __name__ == "__main__":
    main()
