"""Public inputs of the avoidance family: the separator refuses what it cannot separate,
naming the argument, instead of returning NaN; an MPC scenario without casadi is refused
at validation, naming the extra to install."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.avoidance import gaussian_separator
from robofleet.core.errors import ConfigError

I2 = np.eye(2) * 0.01


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (([np.nan, 0.0], I2, [1.0, 0.0], I2), "mean_i: expected finite numbers"),
        (([0.0, 0.0], I2, [np.inf, 0.0], I2), "mean_j: expected finite numbers"),
        (([0.0, 0.0], [[1.0, 0.5], [0.0, 1.0]], [1.0, 0.0], I2), "cov_i: expected symmetric"),
        (([0.0, 0.0], I2, [1.0, 0.0], [[1.0, 0.0], [0.0, -1.0]]), "cov_j: expected positive semi-definite"),
        (([1.0, 2.0], I2, [1.0, 2.0], I2), "expected distinct means"),
        (([0.0, 0.0], I2, [1.0, 0.0, 0.0], I2), "mean_i, mean_j: expected arrays (..., d) with the same d"),
        (([0.0, 0.0], np.eye(3), [1.0, 0.0], I2), "cov_i: expected an array (..., 2, 2)"),
        ((np.zeros((3, 2)), I2, np.ones((4, 2)), I2), "expected leading axes that broadcast"),
        ((["a", "b"], I2, [1.0, 0.0], I2), "mean_i: expected an array of numbers"),
    ],
)
def test_bad_arguments_are_config_errors_naming_the_argument(args, words):
    with pytest.raises(ConfigError) as info:
        gaussian_separator(*args)
    assert words in str(info.value) and isinstance(info.value, ValueError)


def test_valid_singular_covariances_still_separate():
    a, b = gaussian_separator([0.0, 0.0], np.zeros((2, 2)), [2.0, 0.0], np.diag([0.0, 0.04]))
    assert np.all(np.isfinite(a)) and np.isfinite(b) and a[0] > 0.99


def test_an_mpc_scenario_without_casadi_is_refused_at_validation_naming_the_extra(monkeypatch):
    import importlib.util

    import robofleet
    from robofleet.core.errors import ScenarioError

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "casadi" else real(name, *a))
    with pytest.raises(ScenarioError, match=r"teams\.0\.model\.controller: expected an installed casadi .*robofleet\[mpc\]"):
        robofleet.load_scenario("avoidance/quadrotors_3d")


def test_simulate_refuses_what_is_not_a_validated_scenario():
    from robofleet.avoidance import simulate
    from robofleet.core.errors import ConfigError

    for bad in (None, {"family": "avoidance"}, "avoidance/circle_swap"):
        with pytest.raises(ConfigError, match=r"spec: expected a validated avoidance scenario"):
            simulate(bad, seed=1)
