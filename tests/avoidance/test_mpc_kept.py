"""A built MPC problem is kept per thread and reused by the next controller built alike
(the runs of a sweep): a kept problem gives the trace a fresh build gives, and no QP solver
(qpOASES hot-starts from its previous call) is shared between controllers."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

import robofleet
from robofleet.avoidance import mpc

SHORT = {"max_steps": 12}


def run(name: str, seed: int, overrides: dict | None = None) -> robofleet.Trace:
    return robofleet.simulate(robofleet.load_scenario(name, {**SHORT, **(overrides or {})}), seed=seed)


def in_new_thread(name: str, seed: int, overrides: dict | None = None) -> robofleet.Trace:
    """The run in a thread of its own: its controllers build their problems afresh."""
    with ThreadPoolExecutor(1) as pool:
        return pool.submit(run, name, seed, overrides).result()


def assert_same_run(a: robofleet.Trace, b: robofleet.Trace) -> None:
    """Every recorded array equal, but the steps' compute times."""
    assert a.arrays.keys() == b.arrays.keys()
    for key in a.arrays.keys() - {"step_seconds"}:
        np.testing.assert_array_equal(a.arrays[key], b.arrays[key], err_msg=key)


def test_a_kept_quadrotor_problem_gives_the_fresh_build_s_trace():
    first = run("avoidance/quadrotors_3d", seed=3)
    kept = run("avoidance/quadrotors_3d", seed=3)  # this thread keeps the problem the first run built
    assert_same_run(first, kept)
    assert_same_run(first, in_new_thread("avoidance/quadrotors_3d", seed=3))


def test_runs_in_threads_side_by_side_give_each_run_s_own_trace():
    seeds = [5, 6, 5, 6]
    with ThreadPoolExecutor(2) as pool:
        traces = list(pool.map(lambda seed: run("avoidance/quadrotors_3d", seed), seeds))
    assert_same_run(traces[0], traces[2])
    assert_same_run(traces[1], traces[3])
    assert_same_run(traces[0], run("avoidance/quadrotors_3d", seed=5))


def test_a_linear_model_s_hot_started_solver_is_its_controller_s_own():
    """qpOASES starts each call from its previous one: a run after another run (with other
    problems in between) equals the same run in a fresh thread."""
    mpc_model = {"model": {"kind": "double_integrator", "a_max": 1.0, "controller": "mpc"}}
    run("avoidance/double_integrator", seed=1, overrides=mpc_model)
    after_another = run("avoidance/double_integrator", seed=2, overrides=mpc_model)
    assert_same_run(after_another, in_new_thread("avoidance/double_integrator", seed=2, overrides=mpc_model))


def test_each_thread_keeps_at_most_its_share_of_problems():
    for horizon in range(2, 4 + mpc.BUILT_PROBLEMS_PER_THREAD):
        run("avoidance/quadrotors_3d", seed=1, overrides={"max_steps": 1, "teams.0.model.mpc.horizon": horizon})
    assert len(mpc._built_problems.kept) <= mpc.BUILT_PROBLEMS_PER_THREAD
