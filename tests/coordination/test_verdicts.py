"""Verdicts that must be right (issue 11): the literal Definition 3 check never crashes
on a valid plan, ``check`` says exactly which guarantees hold, and plan errors name the
plan file."""

from __future__ import annotations

import numpy as np
import pytest
from coordination_instances import fig2_example, random_instance, roundabout_instance

from robofleet import load_scenario
from robofleet.coordination.coordination_space import build_coordination_space
from robofleet.coordination.guarantees import check
from robofleet.coordination.label_flipping import KnownProbabilities
from robofleet.coordination.plan_execution import Method, PlanExecutor, Variant
from robofleet.coordination.segment_graph import (
    IncrementalCycleDetector,
    Resolution,
    build_segment_layout,
    has_cycle_full,
)
from robofleet.coordination.trajectories import save_trajectories
from robofleet.core.errors import InfeasibleError, ScenarioError


class ReferenceCheckedDetector(IncrementalCycleDetector):
    """Asserts every answer equals the reference: the flip is kept iff the active subgraph
    of the tentative labels has no cycle."""

    answers = 0

    def try_flip(self, obstacle, new_label, progress=None):
        tentative = self.labels.copy()
        tentative[obstacle] = new_label
        expected = not has_cycle_full(self.layout, tentative, np.asarray(progress))
        got = super().try_flip(obstacle, new_label, progress)
        assert got == expected
        type(self).answers += 1
        return got


def run(traj, space, method, check_on, resolution=Resolution.EXACT, seed=0, p=0.3, **kw):
    """One execution; ``p`` is the disturbance probability, one number or one per robot."""
    p = np.broadcast_to(np.reshape(p, (-1, 1)), traj.positions.shape[:2]).copy()
    return PlanExecutor(traj, space, Variant(method, check_on), KnownProbabilities(p, traj.dt), p,
                        resolution=resolution, **kw).run(seed, 20000)


def literal_graph_cyclic(space, n_robots):
    """Whether the literal Definition 3 graph of the plan's own labels has a cycle."""
    literal = build_segment_layout(space, Resolution.DEFINITION3)
    return has_cycle_full(literal, space.initial_labels, np.full(n_robots, -1))


# ---------------------------------------------------------------- definition3
def test_definition3_check_executes_every_roundabout_plan():
    """Plain RMTRACK finishes each roundabout plan; the literal Definition 3 graph of the
    plan's own labels is often cyclic there (the check raised InfeasibleError on those);
    the check with every flip wanted now finishes them too."""
    cyclic = 0
    for seed in range(10):
        traj, space = roundabout_instance(np.random.default_rng(seed), 6)
        cyclic += literal_graph_cyclic(space, traj.n_robots)
        plain = run(traj, space, Method.RMTRACK, False)
        assert plain.finished and not plain.deadlock and plain.collisions == 0
        checked = run(traj, space, Method.TFF, True, Resolution.DEFINITION3, flip_test=lambda ctx: True)
        assert checked.finished and not checked.deadlock and checked.collisions == 0, seed
    assert cyclic >= 3, "the roundabout exercises plans whose literal graph is cyclic"


def test_definition3_answers_like_the_reference_on_cyclic_plans():
    """Crossing plans whose literal graph is cyclic at the plan's labels: every flip
    answer equals the reference test, and every run finishes without deadlock."""
    ReferenceCheckedDetector.answers = 0
    for n, seed in ((6, 67), (6, 78), (5, 168)):
        traj, space, _ = random_instance(np.random.default_rng(seed), n, ring=True)
        assert literal_graph_cyclic(space, n)
        for run_seed in range(6):
            p = np.random.default_rng(run_seed).uniform(0.0, 0.8, n)
            checked = run(traj, space, Method.TFF, True, Resolution.DEFINITION3, seed=run_seed, p=p,
                          flip_test=lambda ctx: True, detector=ReferenceCheckedDetector)
            assert checked.finished and not checked.deadlock and checked.collisions == 0, (seed, run_seed)
    assert ReferenceCheckedDetector.answers >= 20


def test_a_cyclic_literal_graph_refuses_flips_until_the_cycle_is_passed():
    traj, space = next(inst for seed in range(20) for inst in [roundabout_instance(np.random.default_rng(seed), 6)]
                       if literal_graph_cyclic(inst[1], 6))
    literal = build_segment_layout(space, Resolution.DEFINITION3)
    detector = IncrementalCycleDetector(literal, space.initial_labels)
    assert detector.order is None
    other = int(space.robot_i[0] + space.robot_j[0] - space.initial_labels[0])
    assert not detector.try_flip(0, other, np.zeros(traj.n_robots, dtype=np.intp))
    assert (detector.labels == space.initial_labels).all()
    passed = traj.lengths.copy()  # every segment entered: the active subgraph is empty
    assert detector.try_flip(0, other, passed) and detector.order is not None and detector.labels[0] == other


def test_the_exact_detector_still_refuses_cyclic_labels():
    """Only the literal graph may be cyclic on a valid plan; cyclic labels in the exact
    graph are a real inconsistency and stay an error."""
    traj = fig2_example()
    space = build_coordination_space(traj)
    layout = build_segment_layout(space)
    rng = np.random.default_rng(3)
    for _ in range(200):
        labels = np.where(rng.random(space.n_obstacles) < 0.5, space.robot_i, space.robot_j)
        if has_cycle_full(layout, labels, np.full(traj.n_robots, -1)):
            break
    else:
        pytest.fail("no cyclic labelling found")
    with pytest.raises(InfeasibleError, match="without a cycle"):
        IncrementalCycleDetector(layout, labels)


# ---------------------------------------------------------------- check wording
def verdicts(spec, **kw):
    return {g.name: g for g in check(spec, **kw)}


def plan_scenario(tmp_path, traj, policy):
    save_trajectories(traj, tmp_path / "plan.csv")
    lo, hi = traj.positions.min(axis=(0, 1)) - 5, traj.positions.max(axis=(0, 1)) + 5
    box = [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]
    return load_scenario({"family": "coordination", "workspace": {"preset": None, "bounds": box},
                          "robots": {"placement": "explicit", "radius": traj.radius, "starts": traj.starts.tolist(),
                                     "goals": traj.goals.tolist()},
                          "trajectories": str(tmp_path / "plan.csv"), "policy": policy})


def test_check_does_not_promise_no_deadlock_without_definition4():
    g = verdicts(load_scenario("coordination/x_corridor_5_tff"))
    assert not g["non-conflicting"].holds and g["disjoint collision segments"].holds
    theorem4 = g["disjoint collision segments"].line()
    assert "no deadlock" not in theorem4.replace("does not rule out a deadlock", "") and "Definition 4 fails" in theorem4
    assert not g["no deadlock under this policy"].holds
    assert "Definition 4 fails" in g["no deadlock under this policy"].line()
    assert g["collision-free execution"].holds


@pytest.mark.parametrize("policy, holds, words", [
    ({"method": "tff", "deadlock_check": True}, True, "every flip that would close a cycle is refused"),
    ({"method": "tff", "deadlock_check": True, "resolution": "definition3"}, True, "conservative"),
    ({"method": "tff", "deadlock_check": False}, False, "collision segments overlap"),
    ({"method": "rmtrack", "deadlock_check": False}, True, "plan's order"),
])
def test_check_states_the_deadlock_verdict_of_the_policy(tmp_path, policy, holds, words):
    g = verdicts(plan_scenario(tmp_path, fig2_example(), policy))
    assert g["non-conflicting"].holds and not g["disjoint collision segments"].holds
    verdict = g["no deadlock under this policy"]
    assert verdict.holds is holds and words in verdict.line(), verdict.line()


def test_check_without_the_deadlock_check_needs_both_conditions(tmp_path):
    traj, _, _ = random_instance(np.random.default_rng(1), 3, disjoint=True)
    g = verdicts(plan_scenario(tmp_path, traj, {"method": "tff", "deadlock_check": False}))
    assert g["non-conflicting"].holds and g["disjoint collision segments"].holds
    assert g["no deadlock under this policy"].holds
    assert g["disjoint collision segments"].line().endswith("no deadlock")


# ---------------------------------------------------------------- plan files
def test_a_colliding_plan_file_is_refused_naming_the_file(tmp_path):
    traj = fig2_example()
    positions = traj.positions.copy()
    positions[1] = positions[0] + [0.0, 0.5]  # robot 1 drives beside robot 0, half a radius away
    colliding = type(traj)(positions, traj.lengths.copy(), traj.radius, traj.dt)
    with pytest.raises(ScenarioError, match=r"plan\.csv: expected a collision-free plan .*robots 0 and 1 0\.5 apart at plan step 0"):
        plan_scenario(tmp_path, colliding, {"method": "tff"})
