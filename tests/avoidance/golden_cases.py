"""The seeded runs whose trajectories the golden-trace test pins (tests/avoidance/test_golden_traces.py).

Each case is a shipped avoidance scenario, or a random cluttered scene of
:mod:`robofleet.avoidance.random_scenarios`, cut to a small budget, run with the navigation
stages on and off: together they drive every robot model (single and double integrators,
differential drive, quadrotors under the MPC) through every stage (route, detour, yielding,
right-hand rule, band return, recovery). ``python tests/avoidance/golden_cases.py`` writes
the digests of today's code to ``data/golden_traces.json``.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import yaml

import robofleet
from robofleet.avoidance.random_scenarios import random_scenario

HERE = Path(__file__).resolve().parent
SCENARIOS = HERE.parents[1] / "scenarios" / "avoidance"
GOLDEN = HERE / "data" / "golden_traces.json"
PINNED = ("positions", "controls", "arrival_steps")

CASES = {  # name: (source, max_steps, seed)
    "antipodal_swap": ("antipodal_swap", 400, 3),
    "ten_boxes": ("ten_boxes", 500, 1),
    "double_integrator": ("double_integrator", 400, 2),
    "diff_drive": ("diff_drive", 300, 4),
    "heterogeneous": ("heterogeneous", 120, 0),
    "quadrotors_3d": ("quadrotors_3d", 60, 0),
    "random_1005": ("random:1005", 500, 1005),
    "random_di_3001": ("random:3001:double_integrator", 400, 3001),
}


def _mapping(source: str) -> dict:
    """The scenario mapping a case starts from."""
    if source.startswith("random:"):
        parts = source.split(":")
        mapping = random_scenario(int(parts[1]))
        if len(parts) > 2:
            mapping["model"] = {"kind": parts[2], "a_max": 1.0, "controller": "one_step"}
        return mapping
    return yaml.safe_load((SCENARIOS / f"{source}.yaml").read_text())


def case_spec(name: str, navigation: bool, switch) -> object:
    """The validated scenario of a case, its navigation stages switched by ``switch(mapping, on)``."""
    source, steps, _ = CASES[name]
    mapping = {**_mapping(source), "max_steps": steps, "record_cells": False}
    return robofleet.load_scenario(switch(mapping, navigation))


def digest(array: np.ndarray) -> str:
    """SHA-256 of an array's dtype, shape and bytes (bit-identical arrays, same digest)."""
    array = np.ascontiguousarray(array)
    h = hashlib.sha256(f"{array.dtype.str}{array.shape}".encode())
    h.update(array.tobytes())
    return h.hexdigest()


def case_digests(name: str, navigation: bool, switch) -> dict[str, str]:
    """Digests of the pinned arrays of one seeded run."""
    trace = robofleet.simulate(case_spec(name, navigation, switch), seed=CASES[name][2])
    return {key: digest(trace.arrays[key]) for key in PINNED}


def navigation_switch(mapping: dict, on: bool) -> dict:
    """``mapping`` with its navigation stages switched on or off."""
    return {**mapping, "navigation": {**mapping.get("navigation", {}), "enabled": on}}


if __name__ == "__main__":
    table = {f"{name}/{'on' if on else 'off'}": case_digests(name, on, navigation_switch) for name in CASES for on in (True, False)}
    tmp = GOLDEN.with_suffix(".tmp")
    tmp.write_text(json.dumps(table, indent=1, sort_keys=True) + "\n")
    tmp.replace(GOLDEN)
