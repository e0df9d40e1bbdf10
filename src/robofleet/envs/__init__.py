"""robofleet inside learning software: a PettingZoo ``ParallelEnv`` (and its AEC form)
built from any avoidance scenario, with an optional B-UAVC safety filter on the actions.

Needs the optional ``rl`` extra (``pip install 'robofleet[rl]'``: pettingzoo, gymnasium).

* :func:`parallel_env` / :class:`AvoidanceParallelEnv` — the environment;
* :func:`env` — the same as an AEC environment;
* :class:`RewardWeights` — the reward terms' weights.
"""

from .avoidance_env import AvoidanceParallelEnv, RewardWeights, env, parallel_env

__all__ = ["AvoidanceParallelEnv", "RewardWeights", "env", "parallel_env"]
