"""Every search run replays bit for bit: traces and summaries of a seeded sample of the
Fig. 7 sweep's runs, and of runs using every feature of the loop, against digests recorded
from the reference implementation of the loop (one numpy pass per phase of a step).

``trace_digests.json`` holds, per run, a digest of the summary (without ``wall_seconds``),
every array but ``step_seconds`` (compute times), the events and the metadata (without
``wall_seconds``); per algorithm, a digest of the results of a lockstep batch. The grid
sample is 40 runs of ``sweeps/search_fig7.yaml`` (algorithm, robot count, the sweep's seed);
the feature runs cover situation 2, listed and random failures, sonars shorter than
Assumption 2.4 (obstacle collisions), trapezoidal rotation, square and hexagonal grids,
teams above the pairwise collision pre-check and runs longer than one block of draws.
Values are IEEE double arithmetic plus the platform's ``cos``/``sin``/``arctan2``: recorded
on x86-64 with numpy 2.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from robofleet import load_scenario, simulate
from robofleet.search.simulation import build_problem, run_search_batch

DIGESTS = json.loads((Path(__file__).parent / "trace_digests.json").read_text())
FEATURES = {
    "situation2-proposed": {"algorithm": "proposed", "situation": 2, "robots.count": 4},
    "situation2-rule1": {"algorithm": "rule1", "situation": 2, "robots.count": 3},
    "situation2-ru": {"algorithm": "ru", "situation": 2, "robots.count": 5},
    "failures-proposed": {"algorithm": "proposed", "robots.count": 6, "random_failures": {"count": 2, "within_steps": 15}},
    "failures-situation2": {"algorithm": "proposed", "situation": 2, "robots.count": 6,
                            "random_failures": {"count": 3, "within_steps": 25}},
    "failures-ru": {"algorithm": "ru", "robots.count": 7, "random_failures": {"count": 2, "within_steps": 10}},
    "failures-lfp": {"algorithm": "lfp", "robots.count": 5, "random_failures": {"count": 1, "within_steps": 10}},
    "short-sonar-proposed": {"algorithm": "proposed", "robots.count": 4, "ranges.r_so": 0.6, "require_guarantee": False},
    "short-sonar-ru": {"algorithm": "ru", "robots.count": 6, "ranges.r_so": 0.6, "require_guarantee": False},
    "short-sonar-lfp": {"algorithm": "lfp", "robots.count": 6, "ranges.r_so": 0.6, "require_guarantee": False},
    "turning-proposed": {"algorithm": "proposed", "robots.count": 5, "timing.rotation_mode": "trapezoidal"},
    "turning-lfp": {"algorithm": "lfp", "robots.count": 4, "timing.rotation_mode": "trapezoidal"},
    "turning-ru": {"algorithm": "ru", "robots.count": 8, "timing.rotation_mode": "trapezoidal", "grid.a": 0.9,
                   "require_guarantee": False},
    "square-rule1": {"algorithm": "rule1", "robots.count": 5, "grid.kind": "square"},
    "hexagonal-ru": {"algorithm": "ru", "robots.count": 5, "grid.kind": "hexagonal", "require_guarantee": False},
    "large-team-ru": {"algorithm": "ru", "robots.count": 36},
    "large-team-proposed": {"algorithm": "proposed", "robots.count": 36},
    "long-lfp": {"algorithm": "lfp", "robots.count": 1, "max_steps": 700},
}


def digest(trace) -> str:
    """Digest of everything a run decides (see the module docstring)."""
    h = hashlib.sha256()
    summary = {k: v for k, v in trace.summary().items() if k != "wall_seconds"}
    h.update(json.dumps(summary, sort_keys=True).encode())
    for name in sorted(trace.arrays):
        if name == "step_seconds":
            continue
        a = np.ascontiguousarray(trace.arrays[name])
        h.update(f"{name}|{a.dtype}|{a.shape}".encode())
        h.update(a.tobytes())
    h.update(json.dumps(list(trace.events), sort_keys=True).encode())
    meta = {k: v for k, v in trace.metadata.items() if k != "wall_seconds"}
    h.update(json.dumps(meta, sort_keys=True, default=str).encode())
    return h.hexdigest()[:20]


def test_fig7_sample_replays_bit_for_bit():
    specs = {}
    differ = []
    for key, expected in DIGESTS["grid"].items():
        algorithm, count, seed = key.split("/")
        if (algorithm, count) not in specs:
            specs[algorithm, count] = load_scenario("search/fig7", overrides={"algorithm": algorithm, "robots.count": int(count)})
        if digest(simulate(specs[algorithm, count], seed=int(seed))) != expected:
            differ.append(key)
    assert not differ, f"runs that changed: {differ}"


@pytest.mark.parametrize("name", sorted(FEATURES))
def test_feature_runs_replay_bit_for_bit(name):
    spec = load_scenario("search/fig7", overrides=FEATURES[name])
    for seed in (3, 2017):
        assert digest(simulate(spec, seed=seed)) == DIGESTS["features"][f"{name}/{seed}"], (name, seed)


@pytest.mark.parametrize("algorithm", ["proposed", "rule1", "ru", "lfp"])
def test_batches_replay_bit_for_bit(algorithm):
    spec = load_scenario("search/fig7", overrides={"algorithm": algorithm, "robots.count": 4,
                                                   "random_failures": {"count": 1, "within_steps": 30}})
    seeds = [11, 12, 13, 14, 15]
    results = [o.results for o in run_search_batch([build_problem(spec, s) for s in seeds], algorithm, seeds)]
    assert hashlib.sha256(json.dumps(results, sort_keys=True).encode()).hexdigest()[:20] == DIGESTS["batch"][algorithm]
