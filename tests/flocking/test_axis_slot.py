"""Patterns whose on-axis slot the paper's ranking cannot hold (issue 11): a symmetric
pattern whose single on-axis slot is not the nearest to the leader, e.g. a diamond of
seven followers whose axis point is the farthest. ``robofleet check`` says so, and the
opt-in ``algorithm.ranking: axis_slot_nearest`` (beyond the paper) forms them."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from robofleet import load_scenario, simulate
from robofleet.cli.main import app
from robofleet.core.errors import ScenarioError
from robofleet.flocking.basic import BasicAlgorithm
from robofleet.flocking.guarantees import check
from robofleet.flocking.model import LocalFrames
from robofleet.flocking.patterns import validate_points, wedge

from .helpers import world_decisions

SIDES = [[-40, 30], [-40, -30], [-80, 60], [-80, -60], [-120, 30], [-120, -30]]
DIAMOND = SIDES + [[-160, 0]]            # the axis point is the farthest from the leader
FRONT_DIAMOND = SIDES + [[-20, 0]]       # the axis point is the nearest: the paper's ranking holds it
FAST = {"followers": {"area": 200}, "scheduler": {"kind": "fsync"}, "duration": 300}


def diamond_spec(points=DIAMOND, **algorithm):
    return load_scenario({"family": "flocking", "pattern": {"kind": "points", "points": points},
                          "algorithm": {"kind": "basic", **algorithm}, **FAST})


def test_the_axis_slot_must_be_nearer_to_the_leader_than_every_side_slot():
    assert len(validate_points(DIAMOND).axis_slot_ranked_ahead()) == 6
    assert len(validate_points(SIDES + [[-90, 0]]).axis_slot_ranked_ahead()) == 2  # between the side slots
    assert len(validate_points(SIDES + [[-50, 0]]).axis_slot_ranked_ahead()) == 2  # a tie with (-40, ±30): ambiguous
    assert len(validate_points(FRONT_DIAMOND).axis_slot_ranked_ahead()) == 0
    assert len(wedge().axis_slot_ranked_ahead()) == 0                            # no axis point


def test_near_the_formation_the_papers_ranking_sends_the_axis_follower_away():
    """Every follower at its slot except the axis one, 2 units off the axis (beyond the
    0.5 tolerance): the paper's ranking sends it to a side slot and a side follower to
    the axis slot; the variant keeps every follower on its own slot."""
    pattern = validate_points(DIAMOND)
    followers = pattern.points.copy()
    followers[6] += [2.0, 2.0]
    frames = LocalFrames(np.zeros(7), np.ones(7))
    _, paper = world_decisions(BasicAlgorithm(), pattern, np.zeros(2), followers, frames)
    _, variant = world_decisions(BasicAlgorithm(ranking="axis_slot_nearest"), pattern, np.zeros(2), followers, frames)
    assert paper[6] != 6 and 6 in paper
    assert variant == list(range(7))


def test_check_reports_the_diamond_as_unformable_by_the_papers_ranking():
    rows = {g.reference: g for g in check(diamond_spec())}
    assert not rows["Algorithm 1, lines 12-28"].holds and "swap slots" in rows["Algorithm 1, lines 12-28"].line()
    assert not rows["Secs. 4.1, 6.1-6.4"].holds and "axis_slot_nearest" in rows["Secs. 4.1, 6.1-6.4"].line()
    assert rows["Sec. 4.1, item 2"].holds and rows["Sec. 4.1, item 3"].holds  # the paper's own conditions hold
    for spec in (diamond_spec(ranking="axis_slot_nearest"), diamond_spec(FRONT_DIAMOND),
                 load_scenario("flocking/wedge_async")):
        rows = {g.reference: g for g in check(spec)}
        assert rows["Algorithm 1, lines 12-28"].holds and rows["Secs. 4.1, 6.1-6.4"].holds
    chirality = {g.reference: g for g in check(load_scenario({**diamond_spec().model_dump(), "algorithm": {"kind": "chirality"}}))}
    assert not chirality["Secs. 4.1, 6.1-6.4"].holds, "'forms any pattern' does not hold with the distance ranking"


def test_flocking_check_alias_prints_the_warning(tmp_path):
    path = tmp_path / "diamond.yaml"
    path.write_text(f"family: flocking\npattern: {{kind: points, points: {DIAMOND}}}\n")
    result = CliRunner().invoke(app, ["flocking-check", str(path)])
    assert result.exit_code == 0, result.output
    assert "ranking can hold the on-axis slot (Algorithm 1, lines 12-28): no" in result.output


def test_the_papers_ranking_swaps_for_ever_and_the_variant_forms_the_diamond():
    paper, variant = diamond_spec(), diamond_spec(ranking="axis_slot_nearest")
    for seed in range(3):
        swapping = simulate(paper, seed=seed).results
        formed = simulate(variant, seed=seed).results
        assert not swapping["success"] and swapping["slot_changes"] > 10 * max(formed["slot_changes"], 1), seed
        assert formed["success"], seed


def test_the_variant_changes_nothing_without_an_axis_slot():
    base = {"family": "flocking", "pattern": {"kind": "wedge"}, **FAST, "duration": 60}
    paper = simulate(load_scenario({**base, "algorithm": {"kind": "basic"}}), seed=4)
    variant = simulate(load_scenario({**base, "algorithm": {"kind": "basic", "ranking": "axis_slot_nearest"}}), seed=4)
    np.testing.assert_array_equal(paper.positions, variant.positions)


@pytest.mark.parametrize("kind", ["stripe", "hula_hoop"])
def test_the_variant_is_refused_where_the_ranking_is_the_papers_by_construction(kind):
    with pytest.raises(ScenarioError, match=r"algorithm\.ranking: expected 'paper'"):
        load_scenario({"family": "flocking", "algorithm": {"kind": kind, "ranking": "axis_slot_nearest"}})
