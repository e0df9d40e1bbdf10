"""Every example under examples/ runs (at a small size) and says what it promises; one per
family and per embedding API; the worked fifth family keeps its guarantee."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import Delaunay

from markdown_blocks import ROOT, run_command

EXAMPLES = ROOT / "examples"
RUNS = {  # script: (small arguments, a line the output must contain)
    "avoidance_noise.py": (["--robots", "4", "--steps", "150"], "buavc :    0 contact steps"),
    "coordination_label_flipping.py": ([], "RMTRACK+TFA (checked)"),
    "flocking_wedge.py": (["--duration", "60"], "Look-Compute-Move cycles"),
    "search_with_failure.py": ([], "1 failed; search completed: True"),
    "safety_filter_go_to_goal.py": (["--robots", "6", "--steps", "60"], "filtered  : 0 contact pair-steps"),
    "environment_random_policy.py": (["--robots", "12", "--steps", "40"], "safety=buavc: 0 contacts"),
    "supervisor_closed_loop.py": (["--loss", "0.3"], "all robots done: True"),
    "fifth_family/run.py": ([], "conformance: passed"),
}


def test_one_example_per_family_and_embedding_api():
    scripts = {p.relative_to(EXAMPLES).as_posix() for p in EXAMPLES.rglob("*.py") if p.parent.name != "rendezvous"}
    assert scripts == set(RUNS)
    for topic in ("avoidance", "coordination", "flocking", "search", "safety_filter", "environment", "supervisor", "fifth_family"):
        assert any(topic in name for name in scripts), topic


@pytest.mark.parametrize("script", sorted(RUNS))
def test_example_runs(script: str, tmp_path: Path):
    arguments, promise = RUNS[script]
    result = run_command(["python", str(EXAMPLES / script), *arguments], tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert promise in result.stdout, result.stdout


def test_the_supervisor_loop_keeps_robots_apart():
    sys.path.insert(0, str(EXAMPLES))
    try:
        from supervisor_closed_loop import closed_loop
    finally:
        sys.path.remove(str(EXAMPLES))
    for seed in range(2):
        ticks, closest, finished = closed_loop(seed, loss=0.5, delay=0.5)
        assert finished and closest >= 2 * 15.0, (seed, ticks, closest)


def test_rendezvous_keeps_every_robot_in_the_hull():
    """The example family's guarantee, on random configurations, ranges and gains (seeded):
    a consensus step with 0 < g ≤ 1 puts every robot in the convex hull of the robots before it."""
    sys.path.insert(0, str(EXAMPLES / "fifth_family"))
    try:
        from rendezvous.consensus import consensus_step
    finally:
        sys.path.remove(str(EXAMPLES / "fifth_family"))
    rng = np.random.default_rng(2025)
    for _ in range(200):
        n = int(rng.integers(3, 40))
        before = rng.normal(size=(n, 2)) * rng.uniform(0.1, 10)
        after = consensus_step(before, sensing_range=float(rng.uniform(0.01, 20)), gain=float(rng.uniform(1e-3, 1.0)))
        inside = Delaunay(before).find_simplex(after, tol=1e-9) >= 0
        assert inside.all()
