"""The premise of the chance constraint, measured (issue 10, item 3), and per-robot covariances (item 5)."""

import numpy as np
import pytest
import yaml
from scipy.stats import beta

import robofleet
from robofleet import ScenarioError
from robofleet.avoidance.metrics import close_pair_frequencies, premise_shares
from robofleet.avoidance.simulation import simulate
from robofleet.scenarios import catalogue

BASE = yaml.safe_load(catalogue.path("avoidance/three_boxes").read_text())
SHARED = [[0.01, 0.0], [0.0, 0.01]]


def scenario(**robots):
    data = yaml.safe_load(yaml.safe_dump(BASE))
    data["robots"].update(robots)
    return robofleet.load_scenario(data)


def anisotropic_covariances(n, seed):
    """Unequal, rotated, anisotropic Σ_i with standard deviations 0.02–0.1 m (at most the
    shipped scenario's σ = 0.1 m, so the layouts and budgets stay those of the shared case)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        angle = rng.uniform(0, np.pi)
        rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        out.append((rot @ np.diag([rng.uniform(0.05, 0.1) ** 2, rng.uniform(0.02, 0.05) ** 2]) @ rot.T).tolist())
    return out


def test_estimate_in_cell_matches_the_recorded_cells():
    trace = simulate(scenario(), seed=4)
    a = trace.arrays
    inside = a["estimate_in_cell"]
    assert inside.dtype == bool and inside.shape == a["estimates"].shape[:2]
    recomputed = np.all(np.einsum("tnmd,tnd->tnm", a["cell_A"], a["estimates"]) <= a["cell_b"] + 1e-9, axis=2)
    np.testing.assert_array_equal(inside, recomputed)
    assert not np.any(a["empty_cell"] & inside)  # a cell holding its estimate is not empty
    assert 0 < inside.mean() < 1  # noise puts some estimates outside: the share is informative


def test_shares_count_robot_steps_before_arrival():
    trace = simulate(scenario(), seed=4)
    a, r = trace.arrays, trace.results
    steps = np.arange(len(a["estimate_in_cell"]))[:, None]
    moving = (a["arrival_steps"] < 0) | (steps < a["arrival_steps"])
    assert r["estimate_in_cell_share"] == pytest.approx(a["estimate_in_cell"][moving].mean())
    assert r["empty_cell_share"] == pytest.approx(a["empty_cell"][moving].mean())
    assert moving.sum() < moving.size  # arrived robots' steps are left out


def test_premise_shares_by_hand():
    inside = np.array([[True, False], [False, False], [True, True]])
    empty = np.array([[False, True], [False, False], [False, False]])
    shares = premise_shares(inside, empty, np.array([2, -1]))  # robot 0 arrived at step 2
    assert shares["estimate_in_cell_share"] == pytest.approx(2 / 5)
    assert shares["empty_cell_share"] == pytest.approx(1 / 5)


def test_close_pair_rate_by_hand():
    frames = np.array([[[0, 0], [0.3, 0], [5, 5]], [[0, 0], [0.9, 0], [5, 5]], [[0, 0], [3, 0], [5, 5]]], float)
    out = close_pair_frequencies(frames, radius=0.2)
    assert out["close_pair_steps"] == 2
    assert out["close_pair_step_rate"] == pytest.approx(0.5)
    assert np.isnan(close_pair_frequencies(frames[2:], radius=0.2)["close_pair_step_rate"])


def test_orca_has_no_premise():
    data = yaml.safe_load(catalogue.path("avoidance/circle_swap").read_text())
    data["method"] = "orca"
    r = simulate(robofleet.load_scenario(data), seed=0).results
    assert np.isnan(r["estimate_in_cell_share"]) and np.isnan(r["empty_cell_share"])


def test_per_robot_covariances_equal_to_the_shared_one_give_the_same_trace():
    n = BASE["robots"]["n"]
    shared = simulate(scenario(cov=SHARED), seed=7)
    per_robot = simulate(scenario(cov=[SHARED] * n), seed=7)
    for key, value in shared.arrays.items():
        if key != "step_seconds":
            np.testing.assert_array_equal(value, per_robot.arrays[key], err_msg=key)


def test_unequal_anisotropic_covariances_keep_the_chance_constraint_where_its_premise_holds():
    """Unequal rotated Σ_i on seeds nobody tuned: contacts can occur (the bound is δ per
    pair and step, and the premise can fail), so what is tested is the guarantee itself —
    among close pair-steps whose two estimates lay in their own cells, the contact
    frequency is not significantly above δ (one-sided 95 % Clopper–Pearson lower bound)."""
    n, delta = BASE["robots"]["n"], BASE.get("delta", 0.1)
    premised, contacts = 0, 0
    for seed in range(100, 120):
        trace = simulate(scenario(cov=anisotropic_covariances(n, seed)), seed=seed)
        pos, inside = trace.positions, trace.arrays["estimate_in_cell"]
        radius = trace.metadata["radius"]
        gaps = np.linalg.norm(pos[1:, :, None] - pos[1:, None, :], axis=-1)  # after each step
        pairs = np.triu(np.ones((n, n), bool), 1)
        held = inside[:, :, None] & inside[:, None, :] & pairs & (gaps < 1.0)
        premised += int(held.sum())
        contacts += int((held & (gaps < 2 * radius - 1e-7)).sum())
    assert premised > 1000
    lower = float(beta.ppf(0.05, contacts, premised - contacts + 1)) if contacts else 0.0
    assert lower <= delta, (contacts, premised)


def test_per_robot_noise_has_each_robots_covariance():
    n = BASE["robots"]["n"]
    covs = np.array(anisotropic_covariances(n, 0))
    trace = simulate(scenario(cov=covs.tolist()), seed=1)
    errors = trace.arrays["estimates"] - trace.arrays["positions"][:-1]  # the estimation noise itself
    assert len(errors) >= 150
    for i in range(n):
        np.testing.assert_allclose(np.cov(errors[:, i].T), covs[i], atol=0.3 * covs[i].max())


@pytest.mark.parametrize("cov,expected", [
    ([SHARED] * 4, "5 matrices (one per robot)"),
    ([SHARED] * 2 + [[[0.01, 0.02], [0.0, 0.01]]] + [SHARED] * 2, "symmetric matrix for robot 2"),
    ([SHARED] * 4 + [[[-0.01, 0.0], [0.0, 0.01]]], "positive semi-definite matrix (eigenvalues ≥ 0) for robot 4"),
    ([SHARED] * 4 + [[[0.01, 0.0, 0.0], [0.0, 0.01, 0.0]]], "2×2 matrix of finite numbers for robot 4"),
])
def test_per_robot_covariance_errors_name_the_robot(cov, expected):
    with pytest.raises(ScenarioError) as err:
        scenario(cov=cov)
    msg = str(err.value)
    assert "\n" not in msg and "robots.cov" in msg and expected in msg, msg


def test_random_layout_clearances_use_the_largest_sigma():
    from robofleet.avoidance.spec import start_clearances
    n = BASE["robots"]["n"]
    covs = [SHARED] * (n - 1) + [[[0.09, 0.0], [0.0, 0.01]]]
    robot_gap, _, wall_gap = start_clearances(scenario(cov=covs))
    single = start_clearances(scenario(cov=[[0.09, 0.0], [0.0, 0.09]]))
    assert robot_gap == pytest.approx(single[0]) and wall_gap == pytest.approx(single[2])
