"""Every public function refuses bad arguments with a one-line robofleet error that is also
a ValueError or TypeError and names the argument, what was expected and what was
received — never a raw numpy / pathlib / attribute error, never a silent NaN."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import robofleet
from robofleet import (
    Trace,
    Workspace,
    experiments,
    load_scenario,
    scenarios,
    simulate,
    testing,
)
from robofleet import coordination as co
from robofleet import flocking as fl
from robofleet import search as se
from robofleet.avoidance import (
    buffer,
    build_cells,
    confidence_quantile,
    gaussian_separator,
    project_onto_cells,
    shadow_epsilon,
)
from robofleet.core.errors import RobofleetError
from robofleet.core.rng import as_generator, keyed_generator, spawn_seeds
from robofleet.experiments.reproductions import REPRODUCTIONS

I2 = np.eye(2)
SHIPPED = {"avoidance": "avoidance/circle_swap", "coordination": "coordination/fig2_three_robots",
           "flocking": "flocking/wedge_async", "search": "search/fig7"}


def fig7_workspace():
    return load_scenario("search/fig7").workspace.build()


def two_robot_plan():
    return co.make_trajectories([np.zeros((2, 2)), np.full((2, 2), 5.0)], 1.0, 0.1)


MISUSES = {
    # the package's face
    "load_scenario(list)": ("scenario", lambda: load_scenario([1, 2])),
    "load_scenario(None)": ("scenario", lambda: load_scenario(None)),
    "load_scenario(number)": ("scenario", lambda: load_scenario(42)),
    "load_scenario(blank)": ("scenario", lambda: load_scenario("  ")),
    "load_scenario(overrides=list)": ("overrides", lambda: load_scenario("avoidance/circle_swap", overrides=[1])),
    "load_scenario(overrides key)": ("overrides", lambda: load_scenario("avoidance/circle_swap", overrides={1: 2})),
    "load_scenario(overrides NaN)": ("robots.radius", lambda: load_scenario("avoidance/circle_swap", overrides={"robots.radius": math.nan})),
    "load_scenario(overrides index)": ("overrides teams.5.n", lambda: load_scenario("avoidance/heterogeneous", overrides={"teams.5.n": 1})),
    "load_scenario(family)": ("family", lambda: load_scenario({"family": 1})),
    "simulate(None)": ("scenario", lambda: simulate(None)),
    "simulate(float)": ("scenario", lambda: simulate(3.5)),
    "simulate(progress)": ("progress", lambda: simulate("avoidance/circle_swap", seed=1, progress="yes")),
    "simulate(a block, not a scenario)": ("scenario", lambda: simulate(load_scenario("avoidance/circle_swap").robots)),
    "Trace.load(None)": ("directory", lambda: Trace.load(None)),
    "Trace.load(missing)": ("expected a trace directory", lambda: Trace.load("no/such/run")),
    "Workspace(None)": ("bounds", lambda: Workspace(None)),
    "Workspace(NaN)": ("bounds", lambda: Workspace(np.array([[0, 0], [1, 0], [math.nan, 1]]))),
    "Workspace(obstacle)": ("obstacles[0]", lambda: Workspace.rectangle(0, 0, 1, 1, obstacles=[[[0, 0]]])),
    # seeds and generators
    "as_generator(text)": ("rng", lambda: as_generator("x")),
    "as_generator(-1)": ("rng", lambda: as_generator(-1)),
    "spawn_seeds(-1)": ("root", lambda: spawn_seeds(-1, 2)),
    "spawn_seeds(n=-2)": ("n", lambda: spawn_seeds(0, -2)),
    "keyed_generator(text)": ("seed", lambda: keyed_generator("a", 1)),
    # the catalogue
    "scenarios.family": ("family", lambda: scenarios.family("nope")),
    "scenarios.list(kind)": ("kind", lambda: scenarios.list(3)),
    # avoidance
    "gaussian_separator(NaN)": ("mean_i", lambda: gaussian_separator([math.nan, 0], I2, [1, 0], I2)),
    "gaussian_separator(inf)": ("cov_j", lambda: gaussian_separator([0, 0], I2, [1, 0], np.diag([math.inf, 1.0]))),
    "gaussian_separator(asymmetric)": ("cov_i", lambda: gaussian_separator([0, 0], [[1, 0.5], [0, 1]], [1, 0], I2)),
    "gaussian_separator(indefinite)": ("cov_i", lambda: gaussian_separator([0, 0], [[1, 0], [0, -1]], [1, 0], I2)),
    "gaussian_separator(equal means)": ("mean_i, mean_j", lambda: gaussian_separator([0, 0], I2, [0, 0], I2)),
    "gaussian_separator(shapes)": ("mean_i, cov_i, mean_j, cov_j", lambda: gaussian_separator(np.zeros((3, 2)), I2, np.ones((4, 2)), I2)),
    "confidence_quantile(text)": ("delta", lambda: confidence_quantile("x")),
    "confidence_quantile(1.5)": ("delta", lambda: confidence_quantile(1.5)),
    "shadow_epsilon(-1)": ("delta", lambda: shadow_epsilon(-1)),
    "buffer(NaN radius)": ("radius", lambda: buffer(np.array([[1.0, 0.0]]), I2, math.nan, 1.0)),
    "buffer(shapes)": ("normals", lambda: buffer(np.zeros((2, 4)), I2, 0.2, 1.0)),
    "build_cells(None)": ("estimates", lambda: build_cells(None, None, None, 1.0, None, 2.0)),
    "project_onto_cells(None)": ("cells", lambda: project_onto_cells(None, None)),
    "avoidance.check(None)": ("spec", lambda: robofleet.avoidance.check(None)),
    # coordination
    "make_trajectories(radius)": ("robots.radius", lambda: co.make_trajectories([np.zeros((2, 2))], "a", 0.1)),
    "make_trajectories(None)": ("paths", lambda: co.make_trajectories(None, 1.0, 0.1)),
    "make_trajectories(NaN)": ("trajectories[0]", lambda: co.make_trajectories([np.array([[0, 0], [math.nan, 1]])], 1.0, 0.1)),
    "load_trajectories(None)": ("path", lambda: co.load_trajectories(None, 1.0, 0.1)),
    "build_coordination_space(None)": ("traj", lambda: co.build_coordination_space(None)),
    "build_coordination_space(window=0)": ("window", lambda: co.build_coordination_space(two_robot_plan(), window=0)),
    "check_theory(None)": ("traj", lambda: co.check_theory(None, None)),
    "coordination.simulate(None)": ("spec", lambda: co.simulate(None)),
    # flocking
    "make_pattern(kind)": ("pattern.kind", lambda: fl.make_pattern("nope")),
    "make_pattern(NaN)": ("pattern.points", lambda: fl.make_pattern("points", points=[[0, 0], [math.nan, 1]])),
    "make_pattern(random, 1e9)": ("pattern.n_points", lambda: fl.make_pattern("random", n_points=10**9)),
    "validate_points(text)": ("pattern.points", lambda: fl.validate_points("x")),
    "check_conditions(NaN)": ("v_leader", lambda: fl.check_conditions(math.nan, 0.1, 1.0, [1.0], 1.0, 5.0)),
    "check_conditions(no speeds)": ("speeds", lambda: fl.check_conditions(1.0, 0.1, 1.0, [], 1.0, 5.0)),
    "flocking.simulate(spec of search)": ("spec", lambda: fl.simulate(load_scenario("search/fig7"))),
    # search
    "build_grid(kind)": ("kind", lambda: se.build_grid(fig7_workspace(), "hex9", 1.0, 0.3)),
    "build_grid(a=0)": ("a", lambda: se.build_grid(fig7_workspace(), "triangular", 0.0, 0.3)),
    "build_grid(a tiny)": ("a", lambda: se.build_grid(fig7_workspace(), "triangular", 1e-6, 0.3)),
    "build_grid(None)": ("workspace", lambda: se.build_grid(None, "triangular", 1.0, 0.3)),
    "check_assumptions(NaN)": ("r_rob", lambda: se.check_assumptions(fig7_workspace(), "triangular", 1.0, math.nan, 0.3, 1.3, 1.3, 2.0)),
    "run_search(None)": ("problem", lambda: se.run_search(None, "proposed", 1)),
    "search.check(None)": ("spec", lambda: se.check(None)),
    # experiments and testing
    "plan_sweep(None)": ("sweep", lambda: experiments.plan_sweep(None)),
    "plan_sweep(list)": ("sweep", lambda: experiments.plan_sweep([1])),
    "plan_sweep(no scenario)": ("scenario", lambda: experiments.plan_sweep({"seeds": 1})),
    "plan_sweep(too many seeds)": ("seeds", lambda: experiments.plan_sweep({"scenario": "avoidance/circle_swap", "seeds": 10**9})),
    "run_sweep(executor)": ("executor", lambda: experiments.run_sweep({"scenario": "avoidance/circle_swap", "seeds": 1}, executor="x")),
    "run_sweep(workers=0)": ("workers", lambda: experiments.run_sweep({"scenario": "avoidance/circle_swap", "seeds": 1}, executor="serial", workers=0)),
    "run_sweep(progress)": ("progress", lambda: experiments.run_sweep({"scenario": "avoidance/circle_swap", "seeds": 1}, executor="serial", progress="x")),
    "run_tasks(fn=None)": ("fn", lambda: experiments.run_tasks(None, [], "store")),
    "run_tasks(tasks=5)": ("tasks", lambda: experiments.run_tasks(print, 5, "store")),
    "ResultStore(None)": ("directory", lambda: experiments.ResultStore(None)),
    "summarize_sweep(None)": ("frame", lambda: experiments.summarize_sweep(None)),
    "Budget(seeds=0)": ("seeds", lambda: experiments.Budget(seeds=0)),
    "reproduce(None)": ("reproduction", lambda: experiments.reproduce(None, "out")),
    "reproduce(budget)": ("--budget", lambda: experiments.reproduce(REPRODUCTIONS["buavc"], "out", budget="huge")),
    "check_scenario(steps=0)": ("steps", lambda: testing.check_scenario("avoidance/circle_swap", steps=0)),
    "check_family(name)": ("name", lambda: testing.check_family("nope")),
}
for family, name in SHIPPED.items():
    for seed in ("abc", -1, 1.5, True, 2**64):
        MISUSES[f"simulate({family}, seed={seed!r})"] = ("seed", lambda name=name, seed=seed: simulate(name, seed=seed))
    MISUSES[f"FAMILY.check(None) [{family}]"] = ("spec", lambda family=family: scenarios.FAMILIES[family].check(None))
    MISUSES[f"FAMILY.simulate(None) [{family}]"] = ("spec", lambda family=family: scenarios.FAMILIES[family].simulate(None))


@pytest.mark.parametrize("case", sorted(MISUSES))
def test_misuse_is_a_one_line_robofleet_error_naming_the_argument(case, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing a refused call might write lands in the checkout
    argument, call = MISUSES[case]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning before the error
        with pytest.raises(RobofleetError) as info:
            call()
    error, message = info.value, str(info.value)
    assert isinstance(error, (ValueError, TypeError)), type(error).__mro__
    assert "\n" not in message and argument in message, message
    assert "expected" in message and "received" in message, message
    assert not list(tmp_path.iterdir()), "a refused call wrote files"


def test_there_are_at_least_thirty_misuses_across_every_layer():
    assert len(MISUSES) >= 30
    assert {"load_scenario", "gaussian_separator", "make_trajectories", "make_pattern", "build_grid", "run_sweep"} <= {
        case.split("(")[0] for case in MISUSES}


def test_no_silent_nan_leaves_the_separator_or_the_buffer():
    a, b = gaussian_separator([0.0, 0.0], I2, [1.0, 0.0], 0.5 * I2)
    assert np.all(np.isfinite(a)) and np.isfinite(b)
    assert np.all(np.isfinite(buffer(np.array([[1.0, 0.0], [0.0, 1.0]]), I2, 0.2, 1.6)))
    with pytest.raises(RobofleetError, match="finite"):
        buffer(np.array([[1e308, 1e308]]), I2 * 1e308, 0.2, 1.6)  # overflow is refused, not returned
