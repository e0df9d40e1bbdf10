"""The random scene generators: by name, reproducible, the shipped budget rule, valid scenes,
and every seed terminates (a jammed end of the room holds fewer robots)."""

from __future__ import annotations

import numpy as np
import pytest

import robofleet
from robofleet.avoidance import random_scenarios
from robofleet.avoidance.random_scenarios import GENERATORS, ROBOTS, ROOM, room_scene, scene
from robofleet.avoidance.spec import straight_line_budget
from robofleet.core.errors import ConfigError


@pytest.mark.parametrize("generator", sorted(GENERATORS))
@pytest.mark.parametrize("seed", [20000, 70003])
def test_each_generator_is_reproducible_and_uses_the_shipped_budget_rule(generator, seed):
    mapping = scene(generator, seed)
    assert mapping == GENERATORS[generator](seed) and mapping != scene(generator, seed + 1)
    spec = robofleet.load_scenario(mapping)
    assert ROBOTS[0] <= spec.robots.n <= ROBOTS[1]
    assert spec.max_steps == straight_line_budget(spec)


def test_an_unknown_generator_is_refused_in_one_line():
    with pytest.raises(ConfigError, match=r"^generator: expected one of polygons, boxes, room, received 'rooms'$"):
        scene("rooms", 0)


def test_a_room_end_that_jams_holds_fewer_robots_and_the_draw_stops(monkeypatch):
    """Seed 70001 draws more robots than random sequential placement fits into one end of
    the room: the draw stops after PLACEMENT_DRAWS candidates (cut here to keep the test
    fast) and both ends keep as many robots as the fuller one's partner holds."""
    monkeypatch.setattr(random_scenarios, "PLACEMENT_DRAWS", 5_000)
    placed, free_points = [], random_scenarios.free_points

    def spy(rng, n, x_range, polygons):
        out = free_points(rng, n, x_range, polygons)
        placed.append((n, len(out)))
        return out

    monkeypatch.setattr(random_scenarios, "free_points", spy)
    mapping = room_scene(70001)
    assert any(held < wanted for wanted, held in placed)  # an end jammed
    layout = mapping["robots"]["layout"]
    starts, goals = np.array(layout["starts"]), np.array(layout["goals"])
    n = mapping["robots"]["n"]
    assert len(starts) == len(goals) == n == min(held for _, held in placed) >= ROBOTS[0]
    ends = np.abs(np.concatenate([starts, goals])[:, 0])
    assert np.all((ends >= random_scenarios.END_STRIP) & (ends <= ROOM[0] - 0.45))
    both = np.concatenate([starts, goals])
    left, right = both[both[:, 0] < 0], both[both[:, 0] > 0]
    for end in (left, right):
        gaps = np.linalg.norm(end[:, None] - end[None], axis=2) + np.eye(len(end)) * 9
        assert gaps.min() >= 0.8 - 1e-3
    spec = robofleet.load_scenario(mapping)
    assert spec.max_steps == straight_line_budget(spec)
