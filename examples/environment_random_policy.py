"""A random policy in the PettingZoo environment, with and without the B-UAVC filter.

`robofleet.envs.parallel_env` turns any 2-D single-integrator avoidance scenario into a
PettingZoo ``ParallelEnv`` (extra ``rl``: ``pip install 'robofleet[rl]'``). Actions are
desired velocities; with ``safety="buavc"`` each passes through the safety filter before
the robot moves. The policy here samples every action at random (seeded), the worst
case a learning agent starts from; contacts are counted on true positions.

Run:  python examples/environment_random_policy.py [--robots 32] [--steps 200] [--seed 0]
"""

from __future__ import annotations

import argparse

from robofleet.envs import parallel_env


def episode(safety: str, robots: int, steps: int, seed: int) -> tuple[int, float]:
    """Contacts over one episode and the mean reward per agent-step."""
    env = parallel_env("avoidance/circle_swap", safety=safety, overrides={"robots.n": robots}, max_steps=steps)
    observations, infos = env.reset(seed=seed)
    for k, agent in enumerate(env.possible_agents):
        env.action_space(agent).seed(seed + k)
    contacts, reward, count = 0, 0.0, 0
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)
        contacts += sum(info["contacts"] for info in infos.values())
        reward += sum(rewards.values())
        count += len(rewards)
    env.close()
    return contacts, reward / max(count, 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=32)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for safety in ("none", "buavc"):
        contacts, reward = episode(safety, args.robots, args.steps, args.seed)
        print(f"safety={safety:5s}: {contacts} contacts in {args.steps} steps, mean reward {reward:+.4f} per agent-step")


if __name__ == "__main__":
    main()
