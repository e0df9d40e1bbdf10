"""Every family × every shipped scenario passes the public conformance checker."""

from __future__ import annotations

import numpy as np
import pytest

import robofleet
from robofleet.core.errors import ConfigError
from robofleet.scenarios import FAMILIES, catalogue
from robofleet.testing import check_scenario

SHIPPED = catalogue.names()


def test_every_family_ships_scenarios():
    assert {e.family for e in catalogue.list()} == set(FAMILIES)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenario_conforms(name, tmp_path):
    trace = check_scenario(name, steps=4, workdir=tmp_path)
    assert trace.family == robofleet.load_scenario(name).family


@pytest.mark.parametrize("family", sorted(FAMILIES))
@pytest.mark.parametrize("seed", ["abc", -1, 1.5, True, 2**63, np.float64(3.0)])
def test_seeds_that_are_not_non_negative_integers_are_refused(family, seed):
    name = next(e.name for e in catalogue.list() if e.family == family)
    spec = robofleet.load_scenario(name, {FAMILIES[family].budget: 2})
    with pytest.raises(ConfigError, match="seed: expected a non-negative integer"):
        robofleet.simulate(spec, seed=seed)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_numpy_integer_seeds_are_the_same_seed(family):
    name = next(e.name for e in catalogue.list() if e.family == family)
    spec = robofleet.load_scenario(name, {FAMILIES[family].budget: 2})
    a, b = robofleet.simulate(spec, seed=np.int64(5)), robofleet.simulate(spec, seed=5)
    assert a.seed == b.seed == 5
    np.testing.assert_array_equal(a.positions, b.positions)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_progress_true_shows_the_recorders_bar(family, capsys):
    name = next(e.name for e in catalogue.list() if e.family == family)
    spec = robofleet.load_scenario(name, {FAMILIES[family].budget: 3})
    trace = robofleet.simulate(spec, seed=1, progress=True)
    shown = capsys.readouterr().out
    steps = trace.summary()["n_steps"]
    assert f"{steps}/{steps}" in shown, shown
