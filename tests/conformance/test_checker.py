"""The conformance checker itself: a well-formed family passes, each kind of breach fails."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robofleet.scenarios import registry
from robofleet.testing import ConformanceError, check_scenario

TOY = {"family": "toy", "robots": {"n": 3}, "noise": {"sigma": 0.1}, "steps": 6}


def test_the_toy_family_conforms(toy_family, tmp_path):
    check_scenario(TOY, steps=4, figures=False, workdir=tmp_path)


def replace_family(monkeypatch, **changes):
    family = dataclasses.replace(registry.FAMILIES["toy"], **changes)
    monkeypatch.setitem(registry.FAMILIES, "toy", family)
    return family


def test_a_simulation_that_ignores_its_seed_fails(toy_family, monkeypatch):
    original = registry.FAMILIES["toy"].simulate
    fresh = np.random.default_rng()

    def unseeded(spec, seed=None, progress=False):
        trace = original(spec, seed=seed, progress=progress)
        trace.arrays["positions"] = trace.arrays["positions"] + fresh.standard_normal(trace.positions.shape)
        return trace

    replace_family(monkeypatch, simulate=unseeded)
    with pytest.raises(ConformanceError, match="same seed twice: array 'positions' differs"):
        check_scenario(TOY, figures=False)


def test_undocumented_summary_keys_fail(toy_family, monkeypatch):
    documented = dict(registry.FAMILIES["toy"].results)
    documented.pop("final_spread")
    replace_family(monkeypatch, results=documented)
    with pytest.raises(ConformanceError, match=r"\['final_spread'\] are not documented"):
        check_scenario(TOY, figures=False)


def test_a_missing_figures_module_fails(toy_family):
    with pytest.raises(Exception, match="no_such_module"):
        check_scenario(TOY, figures=True)


def test_declarations_and_budgets_refuse_what_the_driver_cannot_run():
    from robofleet.core.errors import ConfigError
    from robofleet.experiments import Budget, Reproduction, reproduce
    from robofleet.experiments.reproductions import REPRODUCTIONS

    for seeds in (0, -1, 1.5, True):
        with pytest.raises(ConfigError, match="Budget: seeds"):
            Budget(seeds=seeds)
    base = REPRODUCTIONS["buavc"]
    with pytest.raises(ConfigError, match="seed_shares"):
        Reproduction(**{**base.__dict__, "seed_shares": {"buavc_noise": 1.5}})
    with pytest.raises(ConfigError, match="seed_shares"):
        Reproduction(**{**base.__dict__, "seed_shares": {"no_such_sweep": 0.5}})
    with pytest.raises(ConfigError, match="--seeds"):
        reproduce(base, budget="smallest", seeds=0, executor="serial", progress=False)
    assert base.sweep_mapping("buavc_noise", base.budgets["smallest"], seeds=np.int64(2))["seeds"] == 2
