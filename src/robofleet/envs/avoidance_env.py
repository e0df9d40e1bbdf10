"""A PettingZoo ``ParallelEnv`` built from any avoidance scenario (Zhu et al. 2022's
setting): every robot is an agent that chooses a desired velocity; with
``safety="buavc"`` the velocities pass through the B-UAVC safety filter first.

Agents ``robot_0 … robot_{N−1}``, all present from the start.

Observation (``Box``, float32, ``6 + 3K`` values; ``K = max_neighbours``)
    own position estimate ``p̂`` (2), own last applied velocity (2), goal − ``p̂`` (2), then
    ``K`` slots of (neighbour estimate − ``p̂`` (2), present 0/1): the ``K`` nearest robots
    in the ∞-norm inside the local box ``R_loc`` (the robots a B-UAVC sees), zeros where
    fewer are there. Estimates are noisy (``N(0, Σ)``, the scenario's σ) as in the family.
Action (``Box [−v_max, v_max]²``, float32)
    the desired velocity [m/s]: two finite real numbers (any float or integer dtype). The
    robot moves at most ``v_max``: a longer vector, however large (``1e300``), is shortened
    along its direction (:func:`~robofleet.envs.fleet.limited`), then passes through the
    safety filter when it is on. NaN, ±inf, complex, boolean or text values and any shape
    but ``(2,)`` are refused with a one-line :class:`~robofleet.core.errors.ConfigError`
    naming the agent.
Reward per agent and step (weights in :class:`RewardWeights`)
    ``progress × (d_before − d_after)`` (TRUE distance to the goal, metres) ``+ contact ×
    (contacts this step)`` ``+ arrival`` on the step the robot is home.
Termination / truncation per agent
    terminated when the robot is home by the goal checker the simulation and the safety
    filter's users share (:class:`~robofleet.avoidance.navigation.goal.GoalChecker`): its
    own estimate — the one in its observation — is within ``goal_tolerance`` of its goal,
    and from then on it holds, parked there and still seen by the others. Its TRUE
    position may then lie a few σ farther (the trace's ``max_true_goal_distance``).
    Truncated for every agent still active after ``max_steps`` steps (the scenario's,
    unless given). Contacts do not end an episode.
Info per agent
    ``contacts`` this step, ``filtered`` (the filter changed its velocity), and with the
    filter ``estimate_in_cell`` and ``empty_cell`` (the premise of the B-UAVC bound).
Calls
    ``step()``, ``trace()`` and ``render()`` need a ``reset()`` first, and ``step()`` after
    every agent has terminated or been truncated needs another ``reset()``; otherwise a
    one-line :class:`~robofleet.core.errors.ConfigError` says so.
Seeds
    ``reset(seed=s)`` seeds one generator from which the layout (random layouts) and all
    noise of the episode are drawn: the same seed and actions give identical episodes.
    ``reset()`` without a seed continues that generator (Gymnasium's rule).
Rendering
    ``render_mode="rgb_array"``: the current state drawn with the avoidance figures
    (:mod:`robofleet.viz.avoidance`); :meth:`AvoidanceParallelEnv.trace` returns the
    episode so far as a :class:`~robofleet.core.trace.Trace` for ``plot_trace`` /
    ``animate_trace``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, NoReturn

import numpy as np

try:
    from gymnasium import logger, spaces
    from pettingzoo import ParallelEnv
    from pettingzoo.utils import parallel_to_aec
except ImportError as exc:  # pragma: no cover - exercised only without the extra
    raise ImportError("robofleet.envs needs the optional 'rl' extra: pip install 'robofleet[rl]'") from exc

from ..avoidance.navigation.goal import GoalChecker
from ..avoidance.spec import Spec as AvoidanceSpec
from ..core import arguments
from ..core.config import MAX_MAGNITUDE, ScenarioSource, load_spec
from ..core.errors import ConfigError, short_repr
from ..core.rng import as_generator, resolve_seed
from ..core.trace import Trace
from .fleet import Fleet
from .render import EpisodeLog, current_state, frame

ENV_NAME = "robofleet_avoidance_v0"


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the reward terms: per metre of progress, per contact, on arrival; each a
    finite real number of magnitude at most ``1e9`` (else a one-line :class:`ConfigError`)."""

    progress: float = 1.0
    contact: float = -1.0
    arrival: float = 1.0

    def __post_init__(self) -> None:
        for name in ("progress", "contact", "arrival"):
            value = getattr(self, name)
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not abs(float(value)) <= MAX_MAGNITUDE:
                raise ConfigError(f"rewards.{name}: expected a finite real number of magnitude at most {MAX_MAGNITUDE:g}, "
                                  f"received {short_repr(value)}")
            object.__setattr__(self, name, float(value))


def avoidance_spec(scenario: ScenarioSource, overrides: Mapping[str, Any] | None = None) -> AvoidanceSpec:
    """An avoidance spec from a shipped name, a YAML file, a mapping or a spec (:func:`~robofleet.core.config.load_spec`)."""
    return load_spec(scenario, AvoidanceSpec, overrides, argument="scenario")


class AvoidanceParallelEnv(ParallelEnv):
    """The environment (see the module docstring). Build it with :func:`parallel_env`."""

    metadata: ClassVar[dict] = {"name": ENV_NAME, "render_modes": ["rgb_array"], "render_fps": 10, "is_parallelizable": True}

    def __init__(self, spec: AvoidanceSpec, safety: str = "buavc", *, max_steps: int | None = None, max_neighbours: int = 6,
                 rewards: RewardWeights = RewardWeights(), render_mode: str | None = None, record_cells: bool | None = None):
        self.fleet = Fleet(spec, safety)
        self.spec, self.safety = spec, safety
        self.rewards = arguments.instance(rewards, RewardWeights, "rewards", "a RewardWeights(progress=…, contact=…, arrival=…)")
        self.max_steps = spec.max_steps if max_steps is None else checked_count(max_steps, "max_steps", 1)
        self.max_neighbours = checked_count(max_neighbours, "max_neighbours", 0)
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ConfigError(f"render_mode: expected None or one of {self.metadata['render_modes']}, received {render_mode!r}")
        self.render_mode = render_mode
        n = sum(t.n for t in spec.team_specs())
        self.record_cells = (n <= 64) if record_cells is None else arguments.flag(record_cells, "record_cells")
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self.agent_index = {a: i for i, a in enumerate(self.possible_agents)}
        self.v_max = np.concatenate([np.full(t.n, t.v_max) for t in spec.team_specs()])
        self.make_spaces()
        self.agents: list[str] = []
        self._rng: np.random.Generator | None = None
        self.episode_seed: int | None = None
        self.log: EpisodeLog | None = None

    # -- spaces -----------------------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_spaces[self.possible_agents[self.check_agent(agent)]]

    def action_space(self, agent: str) -> spaces.Box:
        return self._action_spaces[self.possible_agents[self.check_agent(agent)]]

    def make_spaces(self) -> None:
        """One observation and one action space per agent (the same objects on every call)."""
        low, high = self.fleet.observation_bounds(self.max_neighbours)
        self._observation_spaces = {a: spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
                                    for a in self.possible_agents}
        self._action_spaces = {a: spaces.Box(-float(v), float(v), shape=(2,), dtype=np.float32)
                               for a, v in zip(self.possible_agents, self.v_max)}

    def check_agent(self, agent: str) -> int:
        if agent not in self.agent_index:
            raise ConfigError(f"agent: expected one of robot_0..robot_{len(self.possible_agents) - 1}, received {short_repr(agent)}")
        return self.agent_index[agent]

    # -- episode ------------------------------------------------------------------------------
    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if seed is not None or self._rng is None:
            self.episode_seed = resolve_seed(seed)
            self._rng = as_generator(self.episode_seed)
        self.fleet.reset(self._rng)
        if self.fleet.safety_filter is not None:
            self.fleet.safety_filter.reset()
        self.goal = GoalChecker.initial(self.fleet.n, self.spec.goal_tolerance)
        self.agents = list(self.possible_agents)
        self.steps, self.episode_contacts = 0, 0
        self.log = EpisodeLog.start(self.fleet)
        obs = self.fleet.observations(self.max_neighbours)
        return {a: obs[i] for i, a in enumerate(self.agents)}, {a: {} for a in self.agents}

    def started(self, call: str) -> EpisodeLog:
        """The episode's log, or a :class:`ConfigError` naming ``call`` before the first ``reset()``."""
        if self.log is None:
            raise ConfigError(f"{call}: expected a call to reset() first, received {call} before any reset()")
        return self.log

    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        self.started("step()")
        if not self.agents:
            raise ConfigError("step(): expected a call to reset() after every agent terminated or was truncated, "
                              "received step() on the finished episode")
        fleet = self.fleet
        desired = self.desired_velocities(actions)
        t0 = time.perf_counter()
        before = fleet.goal_distance()
        outcome = fleet.step(desired)
        after = fleet.goal_distance()
        newly = self.settle_goals()
        self.steps += 1
        self.episode_contacts += int(outcome.contacts.sum())
        reward = self.rewards.progress * (before - after) + self.rewards.contact * outcome.contacts + self.rewards.arrival * newly
        obs = fleet.observations(self.max_neighbours)
        self.log.record(fleet, outcome, time.perf_counter() - t0, self.steps, self.record_cells)
        live = self.agents
        truncate = self.steps >= self.max_steps
        out = ({a: obs[self.agent_index[a]] for a in live},
               {a: float(reward[self.agent_index[a]]) for a in live},
               {a: bool(fleet.arrived[self.agent_index[a]]) for a in live},
               {a: bool(truncate and not fleet.arrived[self.agent_index[a]]) for a in live},
               {a: self.agent_info(self.agent_index[a], outcome) for a in live})
        self.agents = [a for a in live if not (out[2][a] or out[3][a])]
        return out

    def settle_goals(self) -> np.ndarray:
        """Judge this step's estimates with the goal checker: robots home now hold (parked,
        :attr:`Fleet.arrived`); returns the robots that became home at this step."""
        was_home = self.goal.home.copy()
        self.goal.observe(self.fleet.estimates, self.fleet.goals)
        self.goal.settle(holding=True)  # a robot home is parked: it holds from now on
        self.fleet.arrived = self.goal.home.copy()
        return self.goal.home & ~was_home

    def desired_velocities(self, actions: Mapping[str, Any]) -> np.ndarray:
        """``(N, 2)`` desired velocities from the action dict (zero for robots not in it):
        two finite real numbers per agent (see the module docstring), else a one-line
        :class:`ConfigError` naming the agent."""
        if not isinstance(actions, Mapping):
            raise ConfigError(f"actions: expected a mapping agent -> velocity (2,), received {type(actions).__name__}")
        desired = np.zeros((len(self.possible_agents), 2))
        if not actions:
            return desired
        rows = [self.check_agent(agent) for agent in actions]
        values = np.stack([real_pair(action, agent) for agent, action in actions.items()]).astype(float)
        finite = np.all(np.isfinite(values), axis=1)
        if not finite.all():
            agent = list(actions)[int(np.argmin(finite))]
            bad_action(agent, actions[agent])
        desired[rows] = values
        return desired

    def agent_info(self, i: int, outcome) -> dict:
        info = {"contacts": int(outcome.contacts[i]), "filtered": bool(outcome.filtered[i])}
        if self.fleet.safety_filter is not None:
            info.update(estimate_in_cell=bool(outcome.estimate_in_cell[i]), empty_cell=bool(outcome.empty_cell[i]))
        return info

    # -- figures ------------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            logger.warn("render() called without a render_mode; build the environment with render_mode='rgb_array'")
            return None
        log = self.started("render()")
        return frame(current_state(self.fleet, self.steps), log.last_cells())

    def trace(self) -> Trace:
        """The episode so far as a :class:`Trace` (arrays, metadata and the avoidance
        family's per-run results), for :func:`robofleet.viz.avoidance.plot_trace` and
        ``animate_trace``."""
        return self.started("trace()").trace(self.fleet, seed=self.episode_seed, method=self.safety)

    def close(self) -> None:
        """Nothing to release (figures are closed when drawn)."""


def real_pair(action: object, agent: str) -> np.ndarray:
    """``action`` as a ``(2,)`` array of real numbers (integer or float dtype; no boolean,
    complex or text entry), else a one-line :class:`ConfigError` naming the agent."""
    if isinstance(action, (list, tuple)) and any(isinstance(x, (bool, np.bool_)) for x in action):
        bad_action(agent, action)
    try:
        array = np.asarray(action)
    except (TypeError, ValueError):
        bad_action(agent, action)
    if array.shape != (2,) or array.dtype.kind not in "iuf":
        bad_action(agent, action)
    return array


def bad_action(agent: str, action: object) -> NoReturn:
    raise ConfigError(f"actions[{agent!r}]: expected 2 finite numbers (a real velocity), received {short_repr(action)}")


def checked_count(value: object, name: str, least: int) -> int:
    """An integer ``≥ least``, or a :class:`ConfigError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise ConfigError(f"{name}: expected an integer ≥ {least}, received {short_repr(value)}")
    return int(value)


def parallel_env(scenario: ScenarioSource = "avoidance/circle_swap", safety: str = "buavc", *,
                 overrides: Mapping[str, Any] | None = None, **options: Any) -> AvoidanceParallelEnv:
    """The PettingZoo parallel environment of an avoidance scenario.

    Parameters
    ----------
    scenario: a shipped name (``"avoidance/three_boxes"``), a YAML file, a mapping, or a
        spec (:func:`~robofleet.core.config.load_spec`, as ``SafetyFilter.from_spec`` and
        ``Supervisor.from_scenario`` take them).
    safety: ``"buavc"`` (actions pass through the B-UAVC safety filter) or ``"none"``.
    overrides: dotted-path overrides applied to the scenario (``{"robots.n": 20}``).
    options: ``max_steps``, ``max_neighbours``, ``rewards`` (:class:`RewardWeights`),
        ``render_mode`` (``None`` or ``"rgb_array"``), ``record_cells``.
    """
    return AvoidanceParallelEnv(avoidance_spec(scenario, overrides), safety, **options)


def env(scenario: ScenarioSource = "avoidance/circle_swap", safety: str = "buavc", **kwargs: Any):
    """The same environment as a PettingZoo AEC environment (``parallel_to_aec``)."""
    return parallel_to_aec(parallel_env(scenario, safety, **kwargs))
