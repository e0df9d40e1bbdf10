"""The safety-filter node over real topics: its commands are the in-process SafetyFilter's,
an old own pose gives zero velocity, bad input is one log line and the node goes on;
and the staleness rule's inequality (randomized, seeded)."""

from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from robofleet import load_scenario
from robofleet.avoidance import SafetyFilter
from robofleet.avoidance.buffer import confidence_quantile
from robofleet.ros2.filter import FleetView, grown_covariance
from robofleet.ros2.messages import pose_message, stamp_of, twist_message

from ros_harness import Harness, LoggedNode

SCENARIO = "avoidance/circle_swap"
N = 8
T0 = 1000.0


@pytest.fixture(scope="module")
def filter_node():
    node = LoggedNode("ros2", "filter", SCENARIO, "--use-sim-time", "--no-deadlock-memory", "--pose-timeout", "1.0")
    yield node
    node.stop()


class Fleet:
    """The test's side of the filter: the clock, every robot's pose and cmd_vel_nav out;
    cmd_vel and safety_state in."""

    def __init__(self, harness: Harness):
        node = harness.node
        self.harness = harness
        self.clock = node.create_publisher(Clock, "/clock", 10)
        self.poses = [node.create_publisher(PoseWithCovarianceStamped, f"/robot{i}/pose", 10) for i in range(N)]
        self.commands = [node.create_publisher(Twist, f"/robot{i}/cmd_vel_nav", 10) for i in range(N)]
        self.answers: dict[int, np.ndarray] = {}
        self.states: dict[int, str] = {}
        for i in range(N):
            node.create_subscription(Twist, f"/robot{i}/cmd_vel", lambda m, i=i: self.answers.__setitem__(i, np.array([m.linear.x, m.linear.y])), 10)
            node.create_subscription(String, f"/robot{i}/safety_state", lambda m, i=i: self.states.__setitem__(i, m.data), 10)
        harness.spin_until(lambda: all(p.get_subscription_count() > 0 for p in self.poses + self.commands)
                           and all(len(node.get_publishers_info_by_topic(f"/robot{i}/cmd_vel")) > 0 for i in range(N)),
                           what="the filter node's topics")

    def round(self, t: float, estimates: np.ndarray | None, covs: np.ndarray, desired: np.ndarray) -> dict[int, np.ndarray]:
        """Publish the clock, the poses (unless None) and the commands; return every answer."""
        self.clock.publish(Clock(clock=stamp_of(t)))
        if estimates is not None:
            for i in range(N):
                self.poses[i].publish(pose_message(estimates[i], covs[i], t, "map"))
        self.answers, self.states = {}, {}
        for i in range(N):
            self.commands[i].publish(twist_message(desired[i]))
        self.harness.spin_until(lambda: len(self.answers) == N and len(self.states) == N, what="the filter's answers")
        return dict(self.answers)


def random_state(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Eight estimates at least 0.5 m apart inside the workspace, and desired velocities."""
    points: list[np.ndarray] = []
    while len(points) < N:
        p = rng.uniform(-3.0, 3.0, 2)
        if all(np.linalg.norm(p - q) >= 0.5 for q in points):
            points.append(p)
    return np.array(points), rng.uniform(-0.6, 0.6, (N, 2))


def test_filter_commands_equal_the_in_process_safety_filter(filter_node, harness):
    spec = load_scenario(SCENARIO)
    reference = SafetyFilter.from_spec(spec)
    covs = np.broadcast_to(reference.covariances, (N, 2, 2))
    fleet = Fleet(harness)
    rng = np.random.default_rng(2023)
    for k in range(3):
        estimates, desired = random_state(rng)
        t = T0 + k
        fleet.round(t, estimates, covs, desired)  # the poses of this round reach the node
        answers = fleet.round(t, estimates, covs, desired)
        expected = reference.filter(estimates, covs, desired).velocity
        got = np.array([answers[i] for i in range(N)])
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
        assert set(fleet.states.values()) <= {"estimate_in_cell", "estimate_outside_cell", "empty_cell"}


def test_a_robot_whose_own_pose_is_older_than_the_timeout_gets_zero_velocity(filter_node, harness):
    fleet = Fleet(harness)
    estimates, desired = random_state(np.random.default_rng(5))
    covs = np.broadcast_to(0.01 * np.eye(2), (N, 2, 2))
    fleet.round(T0 + 10, estimates, covs, desired)
    fleet.round(T0 + 10, estimates, covs, desired)
    answers = fleet.round(T0 + 12, None, covs, desired)  # the clock moved 2 s past the poses (timeout 1 s)
    assert all(np.array_equal(answers[i], np.zeros(2)) for i in range(N))
    assert set(fleet.states.values()) == {"pose_stale"}


def test_malformed_messages_are_one_log_line_each_and_the_node_goes_on(filter_node, harness):
    fleet = Fleet(harness)
    estimates, desired = random_state(np.random.default_rng(9))
    covs = np.broadcast_to(0.01 * np.eye(2), (N, 2, 2))
    t = T0 + 20
    fleet.round(t, estimates, covs, desired)
    before = fleet.round(t, estimates, covs, desired)
    bad = [pose_message(np.array([np.nan, 0.0]), covs[0], t, "map"),                    # NaN position
           pose_message(estimates[1] + 1.0, covs[1], t, "odom"),                           # wrong frame
           pose_message(estimates[2] + 1.0, np.array([[0.01, 0.0], [0.0, -0.02]]), t, "map")]  # covariance not positive
    for robot, message in enumerate(bad):
        fleet.poses[robot].publish(message)
    fleet.commands[3].publish(twist_message([np.nan, 0.0]))                             # NaN command
    stranger = harness.node.create_publisher(PoseWithCovarianceStamped, "/robot99/pose", 10)  # a robot outside the fleet
    stranger.publish(pose_message(np.zeros(2), covs[0], t, "map"))
    after = fleet.round(t, estimates, covs, desired)  # the node answers, from the poses it held
    for i in range(N):
        np.testing.assert_allclose(after[i], before[i], rtol=0, atol=1e-12)
    harness.spin_until(lambda: any("robot99" in line for line in filter_node.lines), what="the unknown robot's log line")
    assert filter_node.stop() == 0
    warnings = [line for line in filter_node.lines if "WARN" in line]
    expected = {"/robot0/pose: pose.position: expected finite x, y": 1, "/robot1/pose: header.frame_id: expected 'map', received 'odom'": 1,
                "/robot2/pose: pose.covariance: expected a symmetric positive semi-definite": 1,
                "/robot3/cmd_vel_nav: twist: expected finite": 1, "/robot99/pose: robot 99 is not in the fleet": 1}
    for text, count in expected.items():
        assert sum(text in line for line in warnings) == count, (text, warnings)
    assert len(warnings) == len(expected), warnings
    assert not any("Traceback" in line for line in filter_node.lines)


@pytest.mark.parametrize("seed", range(5))
def test_grown_covariance_covers_the_distance_moved_in_every_direction(seed):
    """q √(aᵀ Σ' a) ≥ q √(aᵀ Σ a) + D for random Σ (down to singular), D and directions a;
    adversarial directions: Σ's eigenvectors and their bisectors."""
    rng = np.random.default_rng(seed)
    q = confidence_quantile(0.1)
    root = rng.normal(size=(200, 2, 2)) * rng.choice([0.0, 1e-3, 0.1, 1.0], size=(200, 1, 1))
    covs = root @ np.transpose(root, (0, 2, 1))
    reach = rng.choice([0.0, 1e-6, 0.04, 2.0], size=200)
    grown = grown_covariance(covs, reach, q)
    angles = np.concatenate([rng.uniform(0, 2 * np.pi, 64), np.arange(8) * np.pi / 4])
    for cov, cov2, d in zip(covs, grown, reach):
        vectors = np.linalg.eigh(cov)[1].T
        directions = np.concatenate([np.stack([np.cos(angles), np.sin(angles)], 1), vectors,
                                     (vectors[0] + vectors[1])[None] / np.sqrt(2)])
        before = np.sqrt(np.maximum(np.einsum("ki,ij,kj->k", directions, cov, directions), 0))
        after = np.sqrt(np.einsum("ki,ij,kj->k", directions, cov2, directions))
        assert np.all(q * after >= q * before + d - 1e-12 * (1 + d))
    np.testing.assert_array_equal(grown[reach == 0], covs[reach == 0])


def test_poses_are_grown_by_their_age_against_the_later_of_now_and_the_newest_stamp():
    view = FleetView(3)
    cov = 0.01 * np.eye(2)
    for i, stamp in enumerate([10.0, 9.5, 10.0]):
        view.update(i, np.array([i, 0.0]), cov, stamp, 0.0)
    assert not view.update(0, np.array([5.0, 5.0]), cov, 9.0, 0.0)  # a late (older) pose is dropped
    v_max, q = np.full(3, 0.4), confidence_quantile(0.1)
    same = view.covariances(v_max, q, now=0.0)  # the clock behind the stamps: the newest stamp is the reference
    np.testing.assert_array_equal(same[[0, 2]], [cov, cov])
    np.testing.assert_allclose(same[1], grown_covariance(cov[None], np.array([0.4 * 0.5]), q)[0])
    later = view.covariances(v_max, q, now=11.0)
    np.testing.assert_allclose(later, grown_covariance(np.stack([cov] * 3), 0.4 * np.array([1.0, 1.5, 1.0]), q))
