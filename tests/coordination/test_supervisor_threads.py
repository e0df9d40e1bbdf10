"""Several threads calling the supervisor (its *Threads* claim): every robot driven by its
own thread, seeded random sleeps between the calls and inside every decision, the
thread switch interval at 10 µs. Plans where a robot waits for another's very last
report (a decision made just before that report and kept after it stalls the run for
good), and ring plans with flips: no run stalls (:class:`~supervisor_loops.QuietRounds`:
every thread quiet while the supervisor lets no robot move), none collides, none raises."""

from __future__ import annotations


import numpy as np
import pytest
from coordination_instances import random_instance
from supervisor_loops import World, crossing_instance, executor_for, threaded_loop

from robofleet.coordination import Supervisor


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


def test_a_walker_freed_by_a_report_from_a_starved_thread_is_no_stall():
    # the walker (robot 1) waits for the crosser's (robot 0) very last report; the
    # crosser's thread is starved between its last move and that report while the
    # walker's makes its quiet rounds, then the walker's is starved while the crosser's
    # makes them: every thread quiet, and yet the walker is free
    traj = crossing_instance(np.random.default_rng(0))
    sup = Supervisor(traj, executor=executor_for(traj, "rmtrack"), lookahead=1)
    world = World(sup)

    def rounds(robots, count=1):
        for _ in range(count):
            for i in robots:
                sup.report(i, progress=int(world.x[i]))
                answer = sup.answer(i)
                world.step(i, answer.until if answer.go else -1, disturbed=False)

    while world.x[0] < traj.lengths[0]:
        rounds((0, 1))
    rounds((1,), world.quiet.quiet_rounds)
    rounds((0,), world.quiet.quiet_rounds)
    assert not world.stalled and world.quiet.free_when_quiet == 1 and sup.answer(1).go
    while not world.over:
        rounds((0, 1))
    assert not world.stalled and np.all(world.x >= traj.lengths)
