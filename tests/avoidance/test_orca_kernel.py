"""The compiled ORCA step against the vectorized references and against RVO2.

``data/rvo2_reference.npz`` holds RVO2's (C++, single precision) trajectories of the
small cases of ``benchmarks/vs_rvo2.py`` (``--write-reference`` regenerates it with
``pyrvo``); the crowd case drives most agents into the infeasible-program fallback.
"""

from pathlib import Path

import numpy as np
import pytest

from robofleet.avoidance.orca import (
    OrcaParams,
    halfplane,
    least_violation_velocities,
    orca_halfplanes,
    orca_velocities,
    preferred_velocities,
    program_2d,
    program_3d,
    solve_velocity_lp,
)

REFERENCE = Path(__file__).parent / "data" / "rvo2_reference.npz"
RVO2_CASES = ["head_on", "square_swap", "circle_8", "random_12", "crowd_36"]


def largest_violation(q, n, v):
    return np.max(np.einsum("kd,kd->k", n, q - v))


def random_lines(rng, k, spread):
    n = rng.normal(size=(k, 2))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return rng.uniform(-spread, spread, (k, 2)), n


def test_halfplanes_match_the_vectorized_form():
    rng = np.random.default_rng(0)
    rel_pos, rel_vel, own = rng.normal(size=(500, 2)), rng.normal(size=(500, 2)), rng.normal(size=(500, 2))
    rel_pos[:50] *= 0.1  # overlapping pairs
    q, n = orca_halfplanes(rel_pos, rel_vel, own, 0.4, 2.0, 0.1)
    lines = np.empty((500, 4))
    for t in range(500):
        halfplane(*rel_pos[t], *rel_vel[t], *own[t], 0.4, 2.0, 0.1, lines, t)
    np.testing.assert_allclose(lines[:, :2], q, atol=1e-12)
    np.testing.assert_allclose(lines[:, 2:], n, atol=1e-12)


def test_incremental_program_is_the_exact_nearest_velocity():
    """Sec. 5.1's incremental program finds the optimum the candidate enumeration finds,
    and fails exactly when that one reports infeasibility."""
    rng = np.random.default_rng(1)
    for _ in range(400):
        k = int(rng.integers(1, 11))
        q, n = random_lines(rng, k, 0.8)
        pref = rng.uniform(-2, 2, 2)
        want, feasible = solve_velocity_lp(q[None], n[None], np.ones((1, k), bool), pref[None], 1.0)
        failed, v0, v1 = program_2d(np.column_stack([q, n]), k, 1.0, pref[0], pref[1], False)
        assert (failed == k) == feasible[0]
        if feasible[0]:
            np.testing.assert_allclose([v0, v1], want[0], atol=1e-9)


def test_fallback_program_minimises_the_largest_violation():
    """Sec. 5.2: the incremental 3-D program reaches the exact minimax value of the
    enumeration (:func:`least_violation_velocities`) inside the speed disc."""
    rng = np.random.default_rng(2)
    checked = 0
    for _ in range(400):
        k = int(rng.integers(2, 11))
        q, n = random_lines(rng, k, 2.0)
        lines = np.column_stack([q, n])
        failed, v0, v1 = program_2d(lines, k, 1.0, 0.0, 0.0, False)
        if failed == k:
            continue
        v0, v1 = program_3d(lines, k, failed, 1.0, v0, v1, np.empty((k, 4)), 0)
        ref = least_violation_velocities(q[None], n[None], np.ones((1, k), bool), np.array([1.0]))[0]
        assert v0 * v0 + v1 * v1 <= 1.0 + 1e-9
        assert largest_violation(q, n, np.array([v0, v1])) == pytest.approx(largest_violation(q, n, ref), abs=1e-9)
        checked += 1
    assert checked > 100


@pytest.mark.parametrize("case", RVO2_CASES)
def test_same_velocities_as_rvo2_after_ten_steps(case):
    """Run from RVO2's start for 10 steps on our own: every velocity within 1e-6 of
    RVO2's (which computes in single precision), including the fallback agents."""
    ref = np.load(REFERENCE)
    positions, velocities, goals = ref[f"{case}/positions"], ref[f"{case}/velocities"], ref[f"{case}/goals"]
    params = OrcaParams(neighbor_dist=3.0, max_neighbors=10, time_horizon=2.0)
    pos, vel, fallback = positions[0].copy(), velocities[0].copy(), 0
    for step in range(1, len(positions)):
        vel, infeasible = orca_velocities(pos, vel, preferred_velocities(pos, goals, 0.4, 0.1), 0.2, 0.4, params, 0.1)
        pos = pos + vel * 0.1
        fallback += int(infeasible.sum())
        np.testing.assert_allclose(vel, velocities[step], rtol=0, atol=1e-6)
    np.testing.assert_allclose(pos, positions[-1], rtol=0, atol=1e-6)
    if case == "crowd_36":
        assert fallback >= 100  # the dense crowd exercises Sec. 5.2


@pytest.mark.parametrize("field, args", [
    ("positions", (np.zeros((3, 3)), np.zeros((3, 2)), np.zeros((3, 2)), 0.2, 0.4)),
    ("velocities", (np.zeros((3, 2)), np.zeros((2, 2)), np.zeros((3, 2)), 0.2, 0.4)),
    ("radius", (np.zeros((3, 2)), np.zeros((3, 2)), np.zeros((3, 2)), np.ones(2), 0.4)),
])
def test_mismatched_shapes_are_refused_before_the_kernel(field, args):
    from robofleet.core.errors import ConfigError

    with pytest.raises(ConfigError, match=field):
        orca_velocities(*args, OrcaParams(), 0.1)
