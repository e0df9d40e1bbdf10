"""The PettingZoo environment: PettingZoo's own API and seed tests, identical episodes by
seed, observations, rewards, terminations, the safety filter's effect, figures, errors."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo")
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test

from robofleet.core.errors import ConfigError
from robofleet.envs import RewardWeights, env, parallel_env

DENSE = {"robots.n": 32}  # the circle swap with 32 robots 0.8 m apart: random walks collide


def random_episode(e, seed, actions_seed=None):
    """One episode of the random policy; returns the stacked observations and rewards."""
    obs, _ = e.reset(seed=seed)
    for k, agent in enumerate(e.agents):
        e.action_space(agent).seed((seed if actions_seed is None else actions_seed) * 1000 + k)
    rows = [np.stack([obs[a] for a in e.possible_agents])]
    rewards = []
    while e.agents:
        obs, rew, *_ = e.step({a: e.action_space(a).sample() for a in e.agents})
        rows.append(np.stack([obs[a] for a in sorted(obs)]) if obs else np.zeros((0,)))
        rewards.append([rew[a] for a in sorted(rew)])
    return rows, rewards


@pytest.mark.parametrize("safety", ["buavc", "none"])
def test_pettingzoo_parallel_api_test(safety):
    parallel_api_test(parallel_env("avoidance/three_boxes", safety, max_steps=100), num_cycles=120)


def test_pettingzoo_seed_tests_parallel_and_aec():
    parallel_seed_test(lambda: parallel_env("avoidance/three_boxes", max_steps=60))
    seed_test(lambda: env("avoidance/three_boxes", max_steps=60), num_cycles=60)
    api_test(env("avoidance/ten_boxes", max_steps=40), num_cycles=40)


def test_reset_with_a_seed_makes_episodes_identical():
    e1, e2 = parallel_env("avoidance/three_boxes", max_steps=80), parallel_env("avoidance/three_boxes", max_steps=80)
    a_obs, a_rew = random_episode(e1, 5)
    b_obs, b_rew = random_episode(e2, 5)
    again_obs, again_rew = random_episode(e1, 5)
    assert all(np.array_equal(x, y) and np.array_equal(x, z) for x, y, z in zip(a_obs, b_obs, again_obs))
    assert a_rew == b_rew == again_rew
    other, _ = random_episode(e1, 6, actions_seed=5)
    assert not np.array_equal(other[0], a_obs[0])  # the random antipodal layout follows the seed


def test_observations_hold_the_estimates_goal_and_neighbours_inside_the_local_box():
    e = parallel_env("avoidance/circle_swap", overrides=DENSE, max_neighbours=3)
    obs, _ = e.reset(seed=1)
    fleet = e.fleet
    for i, agent in enumerate(e.possible_agents):
        o = obs[agent]
        assert o.shape == (15,) and o.dtype == np.float32 and e.observation_space(agent).contains(o)
        assert np.allclose(o[:2], fleet.estimates[i], atol=1e-6) and np.allclose(o[4:6], fleet.goals[i] - fleet.estimates[i], atol=1e-5)
        gap = np.abs(fleet.estimates - fleet.estimates[i]).max(axis=1)
        gap[i] = np.inf
        expected = np.sort(gap[gap <= fleet.spec.local_box])[:3]
        slots = o[6:].reshape(3, 3)
        seen = np.abs(slots[slots[:, 2] == 1, :2]).max(axis=1)
        assert np.allclose(np.sort(seen), expected, atol=1e-5)


def test_rewards_terminations_and_truncations_per_agent():
    scenario = {"robots": {"n": 2, "sigma": 0.0, "layout": {"kind": "explicit", "starts": [[-1, 0], [2, 2]], "goals": [[-0.85, 0], [2, -2]]}}}
    e = parallel_env(scenario, "none", max_steps=5, rewards=RewardWeights(progress=2.0, contact=-1.0, arrival=10.0))
    e.reset(seed=0)
    _, rew, term, trunc, info = e.step({"robot_0": [0.4, 0.0], "robot_1": [0.0, -0.4]})
    assert rew["robot_0"] == pytest.approx(2.0 * 0.04) and rew["robot_1"] == pytest.approx(2.0 * 0.04)
    assert not any(term.values()) and not any(trunc.values()) and info["robot_0"] == {"contacts": 0, "filtered": False}
    _, rew, term, trunc, _ = e.step({"robot_0": [0.4, 0.0], "robot_1": [0.0, -0.4]})
    assert term["robot_0"] and rew["robot_0"] == pytest.approx(2.0 * 0.04 + 10.0) and e.agents == ["robot_1"]
    while e.agents:
        _, _, term, trunc, _ = e.step({"robot_1": [0.0, -0.4]})
    assert trunc == {"robot_1": True} and term == {"robot_1": False} and e.steps == 5


def test_random_policy_collides_without_the_filter_and_never_with_it():
    episodes, unfiltered_collided = 4, 0
    for safety in ("none", "buavc"):
        e = parallel_env("avoidance/circle_swap", safety, overrides=DENSE, max_steps=100)
        for seed in range(episodes):
            random_episode(e, seed)
            if safety == "none":
                unfiltered_collided += e.episode_contacts > 0
            else:
                assert e.episode_contacts == 0
                assert e.trace().results["collisions"] == 0
    assert unfiltered_collided >= 3


def test_render_and_trace_use_the_avoidance_figures(tmp_path):
    from robofleet.viz.avoidance import animate_trace, plot_trace

    e = parallel_env("avoidance/three_boxes", render_mode="rgb_array", max_steps=12)
    random_episode(e, 3)
    image = e.render()
    assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8 and image.std() > 0
    trace = e.trace()
    assert trace.positions.shape == (13, 5, 2) and trace.arrays["cell_A"].shape[:2] == (12, 5)
    assert trace.summary()["n_steps"] == 12 and trace.summary()["seed"] == 3
    assert plot_trace(trace, tmp_path / "episode.png").stat().st_size > 0
    assert animate_trace(trace, tmp_path / "episode.gif", max_frames=4).stat().st_size > 0


@pytest.mark.parametrize("build, where", [
    (lambda: parallel_env("avoidance/circle_swap", "cbf"), "safety"),
    (lambda: parallel_env("coordination/fig2_three_robots"), "scenario"),
    (lambda: parallel_env("avoidance/double_integrator"), "scenario"),
    (lambda: parallel_env("avoidance/circle_swap", max_steps=0), "max_steps"),
    (lambda: parallel_env("avoidance/circle_swap", render_mode="human"), "render_mode"),
])
def test_bad_construction_is_a_one_line_error(build, where):
    with pytest.raises(ConfigError, match=rf"^{where}: expected"):
        build()


def test_bad_actions_are_refused():
    e = parallel_env("avoidance/circle_swap")
    e.reset(seed=0)
    with pytest.raises(ConfigError, match=r"^actions\['robot_1'\]: expected 2 finite numbers"):
        e.step({"robot_0": [0.1, 0.0], "robot_1": [np.nan, 0.0]})
    with pytest.raises(ConfigError, match=r"^agent: expected one of robot_0..robot_7"):
        e.step({"robot_9": [0.1, 0.0]})


@pytest.mark.parametrize("call", ["step", "trace", "render"])
def test_calls_before_reset_are_one_line_errors(call):
    e = parallel_env("avoidance/circle_swap", render_mode="rgb_array")
    method = {"step": lambda: e.step({}), "trace": e.trace, "render": e.render}[call]
    with pytest.raises(ConfigError, match=rf"^{call}\(\): expected a call to reset\(\) first, received {call}\(\) before any reset\(\)$"):
        method()
    e.reset(seed=0)
    method()


def test_a_step_after_the_episode_ended_asks_for_a_reset():
    e = parallel_env("avoidance/circle_swap", "none", max_steps=2)
    e.reset(seed=0)
    while e.agents:
        e.step({})
    with pytest.raises(ConfigError, match=r"^step\(\): expected a call to reset\(\) after every agent terminated or was truncated"):
        e.step({})
    e.reset()
    assert e.step({})[3]["robot_0"] is False


@pytest.mark.parametrize("rewards, where", [
    ("x", "rewards"), ({"progress": 1.0}, "rewards"), (None, "rewards"),
    (lambda: RewardWeights(progress=float("nan")), "rewards.progress"), (lambda: RewardWeights(contact=float("-inf")), "rewards.contact"),
    (lambda: RewardWeights(arrival=1e300), "rewards.arrival"), (lambda: RewardWeights(progress=True), "rewards.progress"),
    (lambda: RewardWeights(contact="1"), "rewards.contact"), (lambda: RewardWeights(arrival=1 + 2j), "rewards.arrival"),
])
def test_reward_settings_are_one_line_errors(rewards, where):
    with pytest.raises(ConfigError, match=rf"^{where}: expected .*, received "):
        parallel_env("avoidance/circle_swap", rewards=rewards() if callable(rewards) else rewards)


def test_reward_weights_are_real_numbers():
    weights = RewardWeights(progress=2, contact=np.float32(-0.5), arrival=np.int64(3))
    assert (weights.progress, weights.contact, weights.arrival) == (2.0, -0.5, 3.0)
    assert all(type(w) is float for w in (weights.progress, weights.contact, weights.arrival))
    with pytest.raises(ConfigError, match=r"^record_cells: expected True or False, received 'yes'$"):
        parallel_env("avoidance/circle_swap", record_cells="yes")


BAD_ACTIONS = [np.array([np.inf, 0.0]), np.array([0.0, -np.inf]), np.array([np.nan, 0.0]), np.array([1 + 1j, 0]), [0.1, 1j],
               np.array([0.1, 0.2, 0.3]), np.zeros((1, 2)), np.zeros(0), 0.3, None, "ab", ["0.1", "0.2"], [True, False], [True, 0.2],
               np.array([True, False]), np.array([10**30, 1], dtype=object), [[0.1], [0.2]], {"x": 0.1}]


@pytest.mark.parametrize("safety", ["buavc", "none"])
def test_bad_actions_are_one_line_errors_that_change_nothing(safety):
    e = parallel_env("avoidance/circle_swap", safety)
    e.reset(seed=0)
    positions = e.fleet.positions.copy()
    for action in BAD_ACTIONS:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(ConfigError) as info:
                e.step({"robot_0": [0.1, 0.0], "robot_3": action})
        message = str(info.value)
        assert message.startswith("actions['robot_3']: expected 2 finite numbers (a real velocity), received ") and "\n" not in message
    assert e.steps == 0 and np.array_equal(e.fleet.positions, positions)


@pytest.mark.parametrize("safety", ["buavc", "none"])
def test_huge_actions_are_shortened_along_their_direction_without_warnings(safety):
    """Random directions at magnitudes up to the largest float move every robot exactly as
    the same direction at v_max does (seeded)."""
    rng = np.random.default_rng(20)
    huge, limit = parallel_env("avoidance/circle_swap", safety), parallel_env("avoidance/circle_swap", safety)
    huge.reset(seed=4)
    limit.reset(seed=4)
    v_max = limit.v_max[0]
    for _ in range(15):
        angles = rng.uniform(0, 2 * np.pi, len(huge.agents))
        scales = 10.0 ** rng.uniform(0, 308, len(huge.agents)) * rng.choice([1, 1.7976], len(huge.agents))
        directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
        directions[rng.random(len(directions)) < 0.2, rng.integers(0, 2)] = 0.0  # some along an axis
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            huge.step({a: directions[i] * min(scales[i], 1.7e308) for i, a in enumerate(huge.agents)})
            limit.step({a: directions[i] * v_max for i, a in enumerate(limit.agents)})
        assert np.allclose(huge.fleet.velocity, limit.fleet.velocity, rtol=0, atol=1e-12)
        assert np.allclose(huge.fleet.positions, limit.fleet.positions, rtol=0, atol=1e-12)
        speed = np.linalg.norm(huge.fleet.velocity, axis=1)
        assert np.all(speed <= v_max * (1 + 1e-12))
        if safety == "none":
            assert np.allclose(speed, v_max) and np.allclose(huge.fleet.velocity / v_max, directions, atol=1e-12)


def biased_estimates(e, offset):
    """Make every later estimate the true position plus ``offset`` (a known estimation error)."""
    e.fleet.world.position_noise = lambda rng: np.tile(np.asarray(offset, float), (e.fleet.n, 1))


@pytest.mark.parametrize("safety", ["buavc", "none"])
def test_termination_follows_the_goal_checker_on_the_estimate_not_the_true_position(safety):
    """The env, the simulation and the filter agree on "home": the robot's own estimate
    within the tolerance (navigation/goal.py), whatever its true position."""
    scenario = {"robots": {"n": 2, "sigma": 0.01, "layout": {"kind": "explicit", "starts": [[-1, 0], [2, 2]], "goals": [[-0.85, 0], [2, -2]]}}}
    e = parallel_env(scenario, safety, max_steps=6, rewards=RewardWeights(progress=0.0, contact=0.0, arrival=10.0))
    e.reset(seed=0)
    biased_estimates(e, [0.0, 0.5])  # estimates 0.5 m off: the true position arrives, the estimate does not
    _, _, term, _, _ = e.step({"robot_0": [0.4, 0.0]})
    _, rew, term, _, _ = e.step({"robot_0": [0.4, 0.0]})
    assert np.linalg.norm(e.fleet.positions[0] - e.fleet.goals[0]) <= e.spec.goal_tolerance
    assert not term["robot_0"] and rew["robot_0"] == 0.0 and "robot_0" in e.agents
    biased_estimates(e, [0.0, 0.0])  # the estimate now agrees: home, parked, rewarded once
    _, rew, term, _, _ = e.step({"robot_0": [0.0, 0.0]})
    assert term["robot_0"] and rew["robot_0"] == 10.0 and "robot_0" not in e.agents


def test_a_robot_whose_estimate_is_home_terminates_and_holds_even_when_its_true_position_is_not():
    scenario = {"robots": {"n": 2, "sigma": 0.01, "layout": {"kind": "explicit", "starts": [[-1, 0], [2, 2]], "goals": [[-0.85, 0], [2, -2]]}}}
    e = parallel_env(scenario, "buavc", max_steps=4)
    e.reset(seed=0)
    biased_estimates(e, [0.15, 0.0])  # the estimate reaches the goal one step before the true position
    _, _, term, _, _ = e.step({"robot_0": [0.4, 0.0]})
    assert term["robot_0"] and np.linalg.norm(e.fleet.positions[0] - e.fleet.goals[0]) > e.spec.goal_tolerance
    held = e.fleet.positions[0].copy()
    while e.agents:
        e.step({"robot_1": [0.0, -0.4]})
    assert np.array_equal(e.fleet.positions[0], held)  # parked: it holds from then on
    results = e.trace().results
    assert results["max_true_goal_distance"] >= np.linalg.norm(held - e.fleet.goals[0])
