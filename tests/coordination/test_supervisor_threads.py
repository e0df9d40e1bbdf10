"""Several threads calling the supervisor (its *Threads* claim): every robot driven by its
own thread, seeded random sleeps between the calls and inside every decision, the
thread switch interval at 10 µs. Plans where a robot waits for another's very last
report (a decision made just before that report and kept after it stalls the run for
good), and ring plans with flips: no run stalls, none collides, none raises."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from coordination_instances import random_instance
from supervisor_loops import crossing_instance, executor_for, threaded_loop


@pytest.fixture
def fast_thread_switches():
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)
    yield
    sys.setswitchinterval(interval)


def outcome(world) -> tuple:
    return world.error, world.contacts, world.stalled


@pytest.mark.usefixtures("fast_thread_switches")
def test_one_thread_per_robot_never_stalls_nor_collides_where_a_robot_waits_for_a_last_report():
    bad = []
    for seed in range(200):
        traj = crossing_instance(np.random.default_rng(seed), pairs=1 + seed % 2)
        probability = np.full(traj.positions.shape[:2], 0.1)
        probability[0::2] = 0.5  # the crossers are slow: the walkers wait for them
        world = threaded_loop(executor_for(traj, ("rmtrack", "tff")[seed % 2], probability), seed)
        if outcome(world) != (None, 0, False):
            bad.append((seed, *outcome(world)))
    assert bad == []


@pytest.mark.usefixtures("fast_thread_switches")
def test_one_thread_per_robot_with_flips_on_ring_plans():
    bad = []
    for seed in range(12):
        traj, _, _ = random_instance(np.random.default_rng(seed), 5, ring=True)
        world = threaded_loop(executor_for(traj, ("tff", "tfa")[seed % 2]), seed, lookahead=1 + seed % 3)
        if outcome(world) != (None, 0, False):
            bad.append((seed, *outcome(world)))
    assert bad == []
