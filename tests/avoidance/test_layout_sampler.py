"""The antipodal layout sampler: the same starts, goals and generator state as trying
robot by robot (the reference below), in O(N log N)."""

import numpy as np
import pytest

import robofleet
from robofleet.avoidance.layout import sample_antipodal
from robofleet.avoidance.spec import start_clearances
from robofleet.core.errors import ScenarioError


def robot_by_robot(spec, team, rng, max_tries=10_000):
    """The sampler as the authors' setup reads: each robot tries until its start and goal
    keep the clearances from every earlier robot's, the obstacles and the bounds."""
    lay, n = team.layout, team.n
    robot_gap, obstacle_gap, wall_gap = start_clearances(spec)
    ws = spec.workspace.build()
    center = np.asarray(lay.center)
    starts = np.zeros((n, 2))
    for i in range(n):
        for _ in range(max_tries):
            ang = 2 * np.pi * (i + rng.random()) / n
            s = rng.uniform(lay.r_min, lay.r_max) * np.array([np.cos(ang), np.sin(ang)])
            cand = np.array([center + s, center - s])
            prev = np.vstack([center + starts[:i], center - starts[:i]])
            if len(prev) and np.min(np.linalg.norm(prev[:, None] - cand[None], axis=-1)) < robot_gap:
                continue
            if np.min(ws.boundary_distance(cand)) < wall_gap or np.min(ws.obstacle_distance(cand)) < obstacle_gap:
                continue
            starts[i] = s
            break
        else:
            raise ScenarioError("robots.layout", f"room for robot {i}", n)
    return center + starts, center - starts


@pytest.mark.parametrize("name", ["antipodal_swap", "three_boxes", "ten_boxes"])
def test_same_layout_and_generator_state_as_robot_by_robot(name):
    spec = robofleet.load_scenario(f"scenarios/avoidance/{name}.yaml")
    team = spec.team_specs()[0]
    for seed in range(8):
        ours, ref = np.random.default_rng(seed), np.random.default_rng(seed)
        got, want = sample_antipodal(spec, team, ours), robot_by_robot(spec, team, ref)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
        assert ours.random() == ref.random()  # the noise that follows is drawn from the same state


def test_crowded_ring_with_many_rejections_matches_too():
    spec = robofleet.load_scenario({"family": "avoidance", "workspace": {"bounds": [-12, -12, 12, 12]},
                                    "robots": {"n": 150, "sigma": 0.1, "layout": {"kind": "antipodal", "r_min": 1.0, "r_max": 11.0}}})
    team = spec.team_specs()[0]
    got = sample_antipodal(spec, team, np.random.default_rng(3))
    want = robot_by_robot(spec, team, np.random.default_rng(3))
    assert np.array_equal(got[0], want[0])


def test_no_room_is_refused_naming_the_robot():
    spec = robofleet.load_scenario({"family": "avoidance", "workspace": {"bounds": [-12, -12, 12, 12]},
                                    "robots": {"n": 150, "sigma": 0.1, "layout": {"kind": "antipodal", "r_min": 1.0, "r_max": 11.0}}})
    with pytest.raises(ScenarioError, match="room for robot"):
        sample_antipodal(spec, spec.team_specs()[0], np.random.default_rng(3), max_tries=2)
