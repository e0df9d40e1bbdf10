"""Golden traces: seeded runs of the shipped scenarios, navigation on and off, for every
robot model, reproduce the recorded positions, inputs and arrival steps bit for bit
(cases and digests: :mod:`golden_cases`). A change meant to alter the trajectories
re-records the digests with ``python tests/avoidance/golden_cases.py``, and says so."""

from __future__ import annotations

import json

import pytest

from . import golden_cases as cases

GOLDEN = json.loads(cases.GOLDEN.read_text())
HEAVY = {"double_integrator/on", "random_di_3001/on"}  # the detour re-plans of double integrators


PARAMS = [pytest.param(key, marks=[pytest.mark.slow] if key in HEAVY else [], id=key) for key in sorted(GOLDEN)]


@pytest.mark.parametrize("key", PARAMS)
def test_seeded_run_reproduces_the_golden_trace(key):
    name, mode = key.split("/")
    assert cases.case_digests(name, mode == "on", cases.navigation_switch) == GOLDEN[key]
