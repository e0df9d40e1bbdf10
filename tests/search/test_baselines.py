"""RU (collisions allowed, each costing one more move time) and the grid-adapted LFP."""

from __future__ import annotations

import numpy as np

from robofleet import simulate
from robofleet.search.levy_flight import mantegna_sigma

from .helpers import small_spec


def test_ru_time_is_decision_plus_move_plus_collision_penalty():
    spec = small_spec(**{"robots.count": 8, "algorithm": "ru", "require_guarantee": False})
    total_collisions = 0
    for seed in range(6):
        trace = simulate(spec, seed=seed)
        t = trace.arrays["time"][:, 0, 0]
        pos = trace.positions
        per_step = np.zeros(len(t) - 1, dtype=int)
        for e in trace.events:
            if e["kind"] == "collision":
                per_step[e["step"]] += 1
        moved = np.any(np.linalg.norm(np.diff(pos, axis=0), axis=-1) > 0, axis=1)
        expect = 0.1 + 5.75 * moved + 5.75 * per_step
        np.testing.assert_allclose(np.diff(t), expect, atol=1e-9)
        assert trace.results["collisions"] == per_step.sum()
        total_collisions += per_step.sum()
        # point robots: a collision really is two robots on one vertex or swapping an edge
        for e in trace.events:
            if e["kind"] == "collision":
                k, (i, j) = e["step"], e["robots"]
                v = trace.arrays["vertex"][:, :, 0]
                assert v[k + 1, i] == v[k + 1, j] or (v[k + 1, i] == v[k, j] and v[k + 1, j] == v[k, i])
    assert total_collisions > 0


def test_mantegna_sigma_and_heavy_tail():
    assert np.isclose(mantegna_sigma(1.5), 0.6965745, atol=1e-6)
    rng = np.random.default_rng(0)
    z = rng.standard_normal((2, 400_000))
    s = np.abs(mantegna_sigma(1.5) * z[0] / np.abs(z[1]) ** (1 / 1.5))
    ratio = (s > 5).mean() / (s > 50).mean()
    assert 10 ** 1.5 / 2 < ratio < 10 ** 1.5 * 2  # Pareto tail of exponent beta = 1.5


def test_lfp_finds_all_targets_and_avoids_sensed_robots():
    spec = small_spec(**{"robots.count": 4, "algorithm": "lfp", "require_guarantee": False})
    for seed in range(4):
        trace = simulate(spec, seed=seed)
        assert trace.results["completed"] and trace.results["found_targets"] == 4
        v = trace.arrays["vertex"][:, :, 0]
        for k in range(len(v) - 1):
            for i in range(v.shape[1]):
                if v[k + 1, i] != v[k, i]:
                    assert v[k + 1, i] not in np.delete(v[k], i)  # never into an occupied vertex


def test_proposed_beats_baselines_on_average():
    """Statistical check (fixed seeds) of Fig. 7's ordering at 4 robots: (1),(2)&(3) < LFP."""
    times = {}
    for alg in ("proposed", "lfp"):
        spec = small_spec(**{"robots.count": 4, "algorithm": alg, "require_guarantee": False})
        times[alg] = np.mean([simulate(spec, seed=s).results["search_time"] for s in range(30)])
    assert times["proposed"] < times["lfp"]
