"""Motion timing (Section 4.3, Table 1) and the assumption check (2.4, 2.5, 3.1.1–3.1.3)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robofleet.core.spec_blocks import rounded_rectangle
from robofleet.core.workspace import Workspace
from robofleet.search.assumptions import check_assumptions, max_boundary_turn, narrowest_passage
from robofleet.search.timing import MotionTiming, trapezoid_time


def test_table1_move_time():
    t = MotionTiming()
    assert np.isclose(t.translation_time(1.0), 4.5)
    assert np.isclose(t.move_time(1.0), 5.75)


@given(v=st.floats(0.1, 2.0), acc=st.floats(0.1, 2.0), d=st.floats(0.0, 5.0))
def test_trapezoid_profile_brute_force(v, acc, d):
    """Closed form against integrating the profile: max speed v, accel acc, rest to rest."""
    t = float(trapezoid_time(d, v, acc))
    peak = min(v, np.sqrt(d * acc))
    ramp = peak / acc
    cruise = t - 2 * ramp
    assert cruise >= -1e-9
    assert np.isclose(peak * ramp + peak * cruise, d, atol=1e-9)


def test_trapezoidal_rotation_and_bounds():
    t = MotionTiming(rotation_mode="trapezoidal")
    assert np.isclose(t.rotation_time(np.pi), 1.25)
    assert t.rotation_time(0.0) == 0.0
    assert t.rotation_time(np.pi / 3) < 1.25


TABLE1 = dict(a=1.0, r_rob=0.26, r_safe=0.31, r_so=1.31, r_st=1.31, r_c=2.05)


def rounded_box_area():
    return Workspace(rounded_rectangle((0, 0, 10, 8), 1.5), (np.array([[4.0, 3.0], [6.0, 3.0], [6.0, 5.0], [4.0, 5.0]]),))


def test_table1_satisfies_every_assumption():
    report = check_assumptions(rounded_box_area(), "triangular", **TABLE1)
    assert report.failed() == [] and report.complete_search and report.collision_free


@pytest.mark.parametrize("field, value, name", [("r_so", 1.2, "2.4"), ("r_c", 2.0, "2.5"), ("r_st", 1.0, "3.1.1"), ("r_safe", 0.2, "safety")])
def test_each_range_violation_is_reported(field, value, name):
    report = check_assumptions(rounded_box_area(), "triangular", **{**TABLE1, field: value})
    assert name in [c.name for c in report.failed()]
    assert not report.complete_search


def test_non_triangular_grid_loses_complete_search_only():
    report = check_assumptions(rounded_box_area(), "hexagonal", **TABLE1)
    assert report.failed() == [] and report.vertex_complete and not report.complete_search
    assert "not triangular" in report.guarantee


def test_narrow_passage_and_sharp_pocket():
    narrow = Workspace.rectangle(0, 0, 10, 8, obstacles=[np.array([[1.0, 3.0], [3.0, 3.0], [3.0, 5.0], [1.0, 5.0]])])
    assert np.isclose(narrowest_passage(narrow), 1.0)
    report = check_assumptions(narrow, "triangular", **TABLE1)
    assert "3.1.3" in [c.name for c in report.failed()] and not report.vertex_complete
    # a notch (non-convex obstacle) turns the boundary towards the area: 3.1.2 fails
    notch = np.array([[3.0, 3.0], [7.0, 3.0], [7.0, 5.0], [5.2, 5.0], [5.0, 3.4], [4.8, 5.0], [3.0, 5.0]])
    ws = Workspace(rounded_rectangle_bounds(), (notch,))
    assert max_boundary_turn(ws, 1.31) > 1.0
    # a convex obstacle never fails it
    assert max_boundary_turn(rounded_box_area(), 1.31) <= 1.0


def rounded_rectangle_bounds():
    return rounded_rectangle((0, 0, 10, 8), 1.5)
