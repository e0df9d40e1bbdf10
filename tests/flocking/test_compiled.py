"""The compiled ASYNC engine gives the interpreted engine's trace bit for bit."""

import math

import numpy as np
import pytest

import robofleet
from robofleet.flocking import (BasicAlgorithm, ChiralityAlgorithm, HulaHoopAlgorithm, MemoryAlgorithm, RandomizedAlgorithm,
                                StripeAlgorithm, patterns, schedulers)
from robofleet.flocking.basic import barycenter
from robofleet.flocking.compiled import exact_sum, partials_sum
from robofleet.flocking.leader import LeaderCourse
from robofleet.flocking.model import LocalFrames
from robofleet.flocking.schedulers import SchedulerSpec, compiled_setup, run

COMPILED = [BasicAlgorithm(), StripeAlgorithm(), HulaHoopAlgorithm(), RandomizedAlgorithm()]


def async_run(algorithm, m, seed, compiled, rigidity=0.5, duration=None, pattern=None, turn=0.0):
    """An ASYNC run of ``m`` followers from random starts behind a leader (straight or turning)."""
    rng = np.random.default_rng(seed)
    pattern = pattern or patterns.random_lb_symmetric(m, rng)
    starts = rng.uniform(0, 300, (m, 2))
    speeds = rng.uniform(0.5, 5.0, m)
    spec = SchedulerSpec(kind="async", cycle_min=0.5, cycle_max=1.5, rigidity=rigidity)
    duration = duration or max(600 / m, 6.0)
    course = LeaderCourse.build([150.0, 150.0], 0.3, 0.2, np.array([duration / 2, duration / 2 + 2]), np.array([turn, -turn]))
    frames = LocalFrames.random(m, rng, algorithm.frames)
    algorithm_rng, scheduler_rng = np.random.default_rng(seed + 7), np.random.default_rng(seed + 3)
    res = run(algorithm, pattern, frames, starts, speeds, course, spec, duration=duration, sample_dt=0.5,
              scheduler_rng=scheduler_rng, algorithm_rng=algorithm_rng, compiled=compiled)
    return res, (algorithm_rng.bit_generator.state, scheduler_rng.bit_generator.state)


def assert_same_run(a, b):
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.looks == b.looks
    for name in a.log.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(a.log, name), getattr(b.log, name), err_msg=name)


@pytest.mark.parametrize("algorithm", COMPILED, ids=lambda a: a.name)
@pytest.mark.parametrize("m, seed, rigidity, turn", [(1, 0, 0.5, 0.0), (2, 1, 1.0, 0.05), (3, 2, 0.5, 0.02),
                                                     (7, 3, 0.5, 0.0), (12, 4, 1.0, 0.03), (60, 5, 0.5, 0.01)])
def test_compiled_and_interpreted_runs_are_bit_identical(algorithm, m, seed, rigidity, turn):
    fast, fast_rng = async_run(algorithm, m, seed, True, rigidity, turn=turn)
    slow, slow_rng = async_run(algorithm, m, seed, False, rigidity, turn=turn)
    assert_same_run(fast, slow)
    assert fast_rng == slow_rng  # both streams drawn exactly as often (the algorithm's in the same events)


def test_randomized_ties_are_handed_to_the_interpreted_step():
    """A line pattern of an even size (no axis slot): S_0 followers beyond F_0 toss coins."""
    line = patterns.validate_points([[-60.0, 30.0], [-60.0, -30.0], [-60.0, 90.0], [-60.0, -90.0]])
    fast, fast_rng = async_run(RandomizedAlgorithm(axis_tolerance=40.0), 4, 11, True, pattern=line, duration=60)
    slow, slow_rng = async_run(RandomizedAlgorithm(axis_tolerance=40.0), 4, 11, False, pattern=line, duration=60)
    assert fast_rng == slow_rng
    assert fast_rng[0] != np.random.default_rng(18).bit_generator.state  # coins were drawn
    assert_same_run(fast, slow)


def test_hula_hoop_spiral_moves_are_compiled_too():
    fast, _ = async_run(HulaHoopAlgorithm(), 30, 8, True)
    slow, _ = async_run(HulaHoopAlgorithm(), 30, 8, False)
    assert_same_run(fast, slow)
    straight = np.linalg.norm(fast.log.destination - fast.log.start, axis=1)
    assert np.any(fast.log.path_length > straight + 1e-9)  # some Moves follow the spiral


@pytest.mark.parametrize("name", ["flocking/wedge_async", "flocking/hula_hoop_wedge", "flocking/stripe_spread",
                                  "flocking/random_async"])
def test_scenario_traces_do_not_depend_on_the_engine(name, monkeypatch):
    spec = robofleet.load_scenario(name, {"duration": 40})
    fast = robofleet.simulate(spec, seed=3)
    monkeypatch.setattr(schedulers, "compiled_setup", lambda *args: None)
    slow = robofleet.simulate(spec, seed=3)
    np.testing.assert_array_equal(fast.positions, slow.positions)
    assert fast.events == slow.events
    assert fast.results.keys() == slow.results.keys()
    for key, value in fast.results.items():
        assert value == slow.results[key] or (value != value and slow.results[key] != slow.results[key]), key  # NaN == NaN


@pytest.mark.parametrize("algorithm, kind", [(BasicAlgorithm(ranking="axis_slot_nearest"), "async"), (BasicAlgorithm(), "fsync"),
                                             (BasicAlgorithm(), "ssync"), (MemoryAlgorithm(), "async"),
                                             (ChiralityAlgorithm(), "async")])
def test_other_algorithms_and_schedulers_stay_interpreted(algorithm, kind):
    spec = SchedulerSpec(kind=kind)
    assert compiled_setup(algorithm, patterns.wedge(), spec, LocalFrames.random(6, 0)) is None


def test_randomized_needs_an_lb_symmetric_pattern_to_be_compiled():
    lopsided = patterns.validate_points([[-40.0, 10.0], [-80.0, -30.0], [-60.0, 50.0]])
    frames = LocalFrames.random(3, 0)
    assert compiled_setup(RandomizedAlgorithm(), lopsided, SchedulerSpec(), frames) is None
    assert compiled_setup(RandomizedAlgorithm(), patterns.wedge(), SchedulerSpec(), LocalFrames.random(6, 0)) is not None


def test_exact_sum_is_the_correctly_rounded_sum():
    rng = np.random.default_rng(0)
    for trial in range(3000):
        n = int(rng.integers(1, 400))
        values = [rng.uniform(-500, 500, n), rng.normal(0, 1, n) * 10.0 ** rng.integers(-200, 200, n),
                  np.array([1.0, 2.0**-53, 2.0**-106] * n) * rng.choice([-1, 1])][trial % 3]
        if trial % 5 == 0:  # within a hair of a rounding midpoint
            values = np.append(values, np.spacing(math.fsum(values.tolist())) * rng.choice([-0.5, 0.5]))
        rng.shuffle(values)
        expected = math.fsum(values.tolist())
        assert exact_sum(values) == expected and partials_sum(values) == expected


def test_barycenter_does_not_depend_on_the_order_of_the_points():
    rng = np.random.default_rng(1)
    points = rng.uniform(-1e3, 1e3, (999, 2))
    np.testing.assert_array_equal(barycenter(points), barycenter(points[rng.permutation(999)]))
