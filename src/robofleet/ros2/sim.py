"""A simulated fleet as a ROS 2 node (``robofleet ros2 sim SCENARIO``).

Avoidance scenarios (2-D)
    The starts, goals, radii, speed limits and estimation noise of the scenario (its
    layout drawn from ``seed``, as :func:`robofleet.simulate` draws it). Every step ``dt``
    of simulated time, each robot

    1. moves with the last ``<ns>/cmd_vel`` it received (held for ``cmd_timeout``
       seconds, then zero, like a base's command watchdog; with ``lockstep``, the step
       waits up to ``cmd_timeout`` wall seconds for every robot's answer to this step's poses, and a
       robot without one holds: a closed loop that does not depend on the machine's
       load, as the in-process one): a single integrator
       ``p⁺ = p + sat(u) Δt`` (``linear.x, linear.y`` in the map frame), a unicycle for a
       differential-drive team (``linear.x`` forward, ``angular.z``, saturated; RK2);
    2. publishes ``<ns>/pose``: its true position plus a draw of ``N(0, Σ)`` (the
       scenario's noise), the covariance ``Σ`` filled in, stamped with the simulated time
       (also published on ``/clock``);
    3. with ``nominal="go-to-goal"``, publishes ``<ns>/cmd_vel_nav``: straight to its goal
       from its estimate at the speed limit (a unicycle turns towards it first).

    Goals are published once on ``<ns>/goal`` (latched) and a new ``PoseStamped`` there
    replaces the robot's goal. The run stops once every robot's estimate has come within
    ``goal_tolerance`` of its goal (its arrival, as in-process) or after ``max_steps``; with ``out`` it is written as a
    trace (true positions, estimates, commands; the avoidance family's results judged on
    the true positions) that ``robofleet view`` and ``robofleet export --mcap`` read.

Coordination scenarios
    Each robot follows its plan (the instance of ``seed``, as the supervisor's): one
    plan step per ``dt`` while its progress is below the last ``<ns>/until`` it received,
    and reports ``<ns>/progress`` and ``<ns>/pose`` every step. ``drop`` and ``delay``
    inject faults into both directions (a report's progress and pose together) (each message lost with probability ``drop``,
    else delivered 0 … ``delay`` seconds late, in simulated time, from a seeded
    generator). The run stops when every robot has reached its last step.

``speed`` runs simulated time that many times faster than the wall clock; the other
nodes then follow ``/clock`` (``--use-sim-time``).
"""

from __future__ import annotations

import heapq
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..avoidance.metrics import ControllerCounts, run_results
from ..avoidance.cell_model import team_covariance
from ..avoidance.world import World
from ..core import metrics as core_metrics
from ..core.errors import ConfigError, short_repr
from ..core.rng import as_generator, keyed_generator, resolve_seed
from ..core.trace import Trace
from ..dynamics import unicycle
from ..dynamics.single_integrator import saturate
from .messages import MessageError, goal_message, int_message, pose_message, read_goal, read_step, read_twist, stamp_of, twist_message
from .runtime import DEFAULT_PREFIX, MAP_FRAME, BadInputLog, latched_qos, robot_topic, stream_qos

NOMINALS = ("none", "go-to-goal")
HEADING_GAIN = 2.0
"""Turn rate per radian of heading error of the unicycle's go-to-goal command [1/s]."""


# ---------------------------------------------------------------------------------------
# the avoidance fleet (no ROS here: the node below feeds it)
# ---------------------------------------------------------------------------------------
class AvoidanceFleet:
    """Robots of a 2-D avoidance scenario moving with the commands they receive."""

    def __init__(self, spec: Any, seed: int):
        if spec.dim != 2:
            raise ConfigError(f"SCENARIO: expected a 2-D avoidance scenario, received dimension {spec.dim}")
        teams = spec.team_specs()
        kinds = sorted({t.model.kind for t in teams} - {"single_integrator", "unicycle"})
        if kinds:
            raise ConfigError(f"SCENARIO: expected single-integrator or differential-drive (unicycle) teams, received {kinds}")
        self.spec, self.seed = spec, seed
        self.rng = as_generator(seed)
        self.world = World(spec, self.rng)
        self.n, self.dt = self.world.n, float(spec.dt)
        self.goals = self.world.goals.astype(float).copy()
        self.positions = self.world.starts.astype(float).copy()
        headings = self.world.headings() if self.world.has_headings else np.full(self.n, np.nan)
        self.unicycle = ~np.isnan(headings)
        self.headings = np.where(self.unicycle, headings, 0.0)
        self.v_max = self.world.v_max.astype(float)
        self.omega_max = np.concatenate([np.full(t.n, t.model.omega_max or 0.0) for t in teams])
        self.covs = np.concatenate([np.broadcast_to(team_covariance(t, 2), (t.n, 2, 2)) for t in teams])
        self.estimates = self.sense()
        self.record = {"positions": [self.positions.copy()], "headings": [self.headings.copy()], "estimates": [], "controls": []}
        self.arrival_steps = np.full(self.n, -1, np.int64)
        self.steps = 0

    def sense(self) -> np.ndarray:
        """New estimates: true positions plus one draw of each robot's noise."""
        return self.positions + self.world.position_noise(self.rng)

    def step(self, commands: np.ndarray) -> None:
        """Move every robot one ``dt`` with ``commands (n, 3)`` (linear x, y, angular z) and sense."""
        controls = np.zeros((self.n, 2))
        si = ~self.unicycle
        controls[si] = saturate(commands[si, :2], self.v_max[si])
        self.positions[si] += controls[si] * self.dt
        for i in np.flatnonzero(self.unicycle):
            params = unicycle.UnicycleParams(v_max=self.v_max[i], omega_max=self.omega_max[i])
            control = unicycle.saturate(commands[i, [0, 2]], params)
            state = unicycle.step(np.r_[self.positions[i], self.headings[i]], control, self.dt, params)
            self.positions[i], self.headings[i], controls[i] = state[:2], state[2], control
        self.record["estimates"].append(self.estimates)
        self.record["controls"].append(controls)
        self.steps += 1
        self.record["positions"].append(self.positions.copy())
        self.record["headings"].append(self.headings.copy())
        self.estimates = self.sense()
        arrived = np.linalg.norm(self.estimates - self.goals, axis=1) <= self.spec.goal_tolerance
        self.arrival_steps[arrived & (self.arrival_steps < 0)] = self.steps

    @property
    def finished(self) -> bool:
        return bool(np.all(self.arrival_steps >= 0)) or self.steps >= self.spec.max_steps

    def nominal(self) -> np.ndarray:
        """Straight-to-goal commands ``(n, 3)`` from the current estimates."""
        out = np.zeros((self.n, 3))
        to_goal = self.goals - self.estimates
        out[:, :2] = saturate(to_goal / self.dt, self.v_max)
        for i in np.flatnonzero(self.unicycle):
            error = np.angle(np.exp(1j * (np.arctan2(to_goal[i, 1], to_goal[i, 0]) - self.headings[i])))
            speed = np.linalg.norm(out[i, :2]) * max(np.cos(error), 0.0)
            out[i] = (speed, 0.0, np.clip(HEADING_GAIN * error, -self.omega_max[i], self.omega_max[i]))
        return out

    def trace(self, wall_seconds: float) -> Trace:
        """The run as an avoidance trace (results judged on the true positions)."""
        rec = {k: np.asarray(v, float) for k, v in self.record.items()}
        steps = self.steps
        estimates = rec["estimates"].reshape(steps, self.n, 2)
        controls = rec["controls"].reshape(steps, self.n, 2)
        workspace = self.spec.workspace.build()
        results = run_results(rec["positions"], self.goals, radius=self.spec.robots.radius, dt=self.dt, goal_tolerance=self.spec.goal_tolerance,
                              workspace=workspace, boxes=None, step_seconds=np.zeros(steps), arrivals=self.arrival_steps,
                              counts=ControllerCounts())
        arrays = {"positions": rec["positions"], "estimates": estimates, "controls": controls, "arrival_steps": self.arrival_steps.copy(),
                  "step_seconds": np.zeros(steps)}
        if self.unicycle.any():
            arrays["headings"] = np.where(self.unicycle, rec["headings"], np.nan)
        metadata = {**self.world.metadata(), "goals": self.goals.tolist(), "scenario": self.spec.scenario_name, "seed": self.seed,
                    "n_robots": self.n, "n_steps": steps, "max_steps": self.spec.max_steps, "record_every": 1,
                    "wall_seconds": wall_seconds, "source": "ros2 sim", "robot_covs": self.covs.tolist()}
        return Trace("avoidance", arrays, [], metadata, results, workspace)


# ---------------------------------------------------------------------------------------
# the coordination fleet: plan followers
# ---------------------------------------------------------------------------------------
class PlanFleet:
    """Robots following a coordination scenario's plan up to the step they are permitted."""

    def __init__(self, spec: Any, seed: int):
        from ..coordination.instance import prepare_instance

        self.spec, self.seed = spec, seed
        workspace = spec.build_workspace()
        self.traj = prepare_instance(spec, seed, workspace).trajectories
        self.workspace = workspace
        self.n, self.dt = self.traj.n_robots, float(self.traj.dt)
        self.lengths = np.asarray(self.traj.lengths, np.int64)
        self.progress = np.zeros(self.n, np.int64)
        self.until = np.zeros(self.n, np.int64)
        self.record = {"positions": [self.positions()], "progress": [self.progress.copy()]}
        self.arrival_steps = np.full(self.n, -1, np.int64)
        self.steps = 0

    def positions(self) -> np.ndarray:
        return self.traj.positions[np.arange(self.n), self.progress].astype(float)

    def step(self) -> None:
        """Each robot advances one plan step if it is permitted to."""
        self.progress = np.where(self.progress < np.minimum(self.until, self.lengths), self.progress + 1, self.progress)
        self.steps += 1
        self.record["positions"].append(self.positions())
        self.record["progress"].append(self.progress.copy())
        done = (self.progress >= self.lengths) & (self.arrival_steps < 0)
        self.arrival_steps[done] = self.steps

    @property
    def finished(self) -> bool:
        return bool(np.all(self.progress >= self.lengths)) or self.steps >= self.spec.simulation.max_steps

    def trace(self, wall_seconds: float, faults: dict) -> Trace:
        positions = np.asarray(self.record["positions"], float)
        contacts, nearest = core_metrics.pair_contacts(positions, float(self.traj.radius))
        finished = bool(np.all(self.progress >= self.lengths))
        results = {"success": finished and len(contacts) == 0, "finished": finished, "collision_events": int(len(contacts)),
                   "min_pair_distance": float(nearest.min(initial=np.inf)), "makespan": self.steps * self.dt if finished else None}
        arrays = {"positions": positions, "progress": np.asarray(self.record["progress"])[:, :, None], "arrival_steps": self.arrival_steps.copy(),
                  "plan": np.transpose(self.traj.positions, (1, 0, 2))}
        metadata = {"scenario": self.spec.scenario_name, "seed": self.seed, "n_robots": self.n, "n_steps": self.steps,
                    "record_every": 1, "wall_seconds": wall_seconds, "dt": self.dt, "radius": float(self.traj.radius),
                    "lengths": self.lengths.tolist(), "source": "ros2 sim", **faults}
        return Trace("coordination", arrays, [], metadata, results, self.workspace)


@dataclass(order=True)
class Delayed:
    """A message held back until simulated step ``due``."""

    due: int
    order: int
    deliver: Callable[[], None] = field(compare=False)


class FaultyLink:
    """Loses each message with probability ``drop``, else delays it by 0 … ``delay_steps``
    steps (uniformly, from a seeded generator): late messages may overtake each other."""

    def __init__(self, drop: float, delay_steps: int, rng: np.random.Generator):
        self.drop, self.delay_steps, self.rng = drop, delay_steps, rng
        self.queue: list[Delayed] = []
        self.sent = self.dropped = self.delayed = 0

    def send(self, step: int, deliver: Callable[[], None]) -> None:
        self.sent += 1
        if self.drop and self.rng.random() < self.drop:
            self.dropped += 1
            return
        lag = int(self.rng.integers(0, self.delay_steps + 1)) if self.delay_steps else 0
        if lag == 0:
            deliver()
            return
        self.delayed += 1
        heapq.heappush(self.queue, Delayed(step + lag, self.sent, deliver))

    def flush(self, step: int) -> None:
        """Deliver every message due by ``step``."""
        while self.queue and self.queue[0].due <= step:
            heapq.heappop(self.queue).deliver()


# ---------------------------------------------------------------------------------------
# the node
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SimOptions:
    """The command line's options of ``robofleet ros2 sim``."""

    seed: int = 0
    nominal: str = "none"
    prefix: str = DEFAULT_PREFIX
    speed: float = 1.0
    cmd_timeout: float = 0.5
    out: Path | None = None
    wait_for_cmd_vel: bool = False
    lockstep: bool = False
    drop: float = 0.0
    delay: float = 0.0

    def checked(self) -> SimOptions:
        if self.nominal not in NOMINALS:
            raise ConfigError(f"--nominal: expected one of {list(NOMINALS)}, received {short_repr(self.nominal)}")
        for name, value in (("--speed", self.speed), ("--cmd-timeout", self.cmd_timeout)):
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise ConfigError(f"{name}: expected a number > 0, received {short_repr(value)}")
        if not 0 <= self.drop < 1:
            raise ConfigError(f"--drop: expected a probability in [0, 1), received {short_repr(self.drop)}")
        if not (np.isfinite(self.delay) and self.delay >= 0):
            raise ConfigError(f"--delay: expected seconds ≥ 0, received {short_repr(self.delay)}")
        if self.out is not None:
            check_new_directory(self.out)
        return self


def check_new_directory(out: Path) -> None:
    """``out`` must be a new or empty directory (nothing there is overwritten)."""
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"--out: expected a new or empty directory, received {out}, which {'is a file' if not out.is_dir() else 'holds files'}")


def save_trace(trace: Trace, out: Path) -> None:
    """Write the trace into ``out`` (new or empty, checked at start); both files land
    together, complete (:meth:`Trace.save`)."""
    trace.save(out)


def make_sim_node(spec: Any, options: SimOptions):
    """The simulator node for an avoidance or a coordination scenario."""
    from rclpy.node import Node
    from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Int32

    options = options.checked()
    seed = resolve_seed(options.seed, "--seed")
    coordination = spec.family == "coordination"
    if not coordination and spec.family != "avoidance":
        raise ConfigError(f"SCENARIO: expected an avoidance or a coordination scenario, received a {spec.family} scenario")
    if not coordination and (options.drop or options.delay):
        raise ConfigError("--drop, --delay: expected them with a coordination scenario only, received them with an avoidance scenario")
    fleet: Any = PlanFleet(spec, seed) if coordination else AvoidanceFleet(spec, seed)
    p, qos = options.prefix, stream_qos()

    class SimNode(Node):
        def __init__(self) -> None:
            super().__init__("robofleet_sim")
            self.fleet, self.done, self.started = fleet, False, not options.wait_for_cmd_vel
            self.bad = BadInputLog(self.get_logger())
            self.t0 = time.time()
            self.wall_start = time.perf_counter()
            self.clock = self.create_publisher(Clock, "/clock", 10)
            self.poses = [self.create_publisher(PoseWithCovarianceStamped, robot_topic(p, i, "pose"), qos) for i in range(fleet.n)]
            if coordination:
                self.links = (FaultyLink(options.drop, round(options.delay / fleet.dt), keyed_generator(seed, "ros2-sim", "up")),
                              FaultyLink(options.drop, round(options.delay / fleet.dt), keyed_generator(seed, "ros2-sim", "down")))
                self.progress = [self.create_publisher(Int32, robot_topic(p, i, "progress"), qos) for i in range(fleet.n)]
                for i in range(fleet.n):
                    self.create_subscription(Int32, robot_topic(p, i, "until"), lambda m, i=i: self.on_until(i, m), qos)
            else:
                self.commands = np.zeros((fleet.n, 3))
                self.command_time = np.full(fleet.n, -np.inf)
                self.answered = np.zeros(fleet.n, bool)
                self.published_at = time.perf_counter()
                self.nominal = [self.create_publisher(Twist, robot_topic(p, i, "cmd_vel_nav"), qos) for i in range(fleet.n)] \
                    if options.nominal == "go-to-goal" else None
                self.goal_pubs = [self.create_publisher(PoseStamped, robot_topic(p, i, "goal"), latched_qos()) for i in range(fleet.n)]
                for i in range(fleet.n):
                    self.create_subscription(Twist, robot_topic(p, i, "cmd_vel"), lambda m, i=i: self.on_cmd_vel(i, m), qos)
                    self.create_subscription(PoseStamped, robot_topic(p, i, "goal"), lambda m, i=i: self.on_goal(i, m), latched_qos())
                    self.goal_pubs[i].publish(goal_message(fleet.goals[i], self.sim_time(), MAP_FRAME))
            self.timer = self.create_timer(fleet.dt / options.speed, self.tick)
            self.get_logger().info(f"simulating {fleet.n} robots of {spec.scenario_name or spec.source} (seed {seed}, "
                                   f"dt {fleet.dt:g} s, speed ×{options.speed:g})")

        def sim_time(self) -> float:
            return self.t0 + self.fleet.steps * self.fleet.dt

        # -- inputs --------------------------------------------------------------------------
        def on_cmd_vel(self, i: int, msg) -> None:
            try:
                linear, angular = read_twist(msg)
            except MessageError as exc:
                self.bad(robot_topic(p, i, "cmd_vel"), str(exc))
                return
            self.commands[i] = (*linear, angular)
            self.command_time[i] = time.perf_counter()
            self.answered[i] = True

        def on_goal(self, i: int, msg) -> None:
            try:
                self.fleet.goals[i] = read_goal(msg, MAP_FRAME)
            except MessageError as exc:
                self.bad(robot_topic(p, i, "goal"), str(exc))

        def on_until(self, i: int, msg) -> None:
            try:
                until = read_step(msg, int(self.fleet.lengths[i]))
            except MessageError as exc:
                self.bad(robot_topic(p, i, "until"), str(exc))
                return
            self.links[1].send(self.fleet.steps, lambda: self.fleet.until.__setitem__(i, until))

        # -- the step ------------------------------------------------------------------------
        def tick(self) -> None:
            if self.done:
                return
            if not self.started:
                self.started = all(self.count_publishers(robot_topic(p, i, "cmd_vel")) > 0 for i in range(self.fleet.n)) \
                    if not coordination else all(self.count_publishers(robot_topic(p, i, "until")) > 0 for i in range(self.fleet.n))
                self.publish_state()
                return
            if coordination:
                self.links[1].flush(self.fleet.steps)
                self.fleet.step()
                self.links[0].flush(self.fleet.steps)
            elif options.lockstep:
                waited = time.perf_counter() - self.published_at  # wall seconds: the filter's compute time does not scale
                if not self.answered.all() and waited <= options.cmd_timeout:
                    return  # wait for the missing commands of this step
                self.fleet.step(np.where(self.answered[:, None], self.commands, 0.0))
            else:
                fresh = (time.perf_counter() - self.command_time) * options.speed <= options.cmd_timeout
                self.fleet.step(np.where(fresh[:, None], self.commands, 0.0))
            self.publish_state()
            if self.fleet.finished:
                self.done = True

        def publish_state(self) -> None:
            now = self.sim_time()
            self.clock.publish(Clock(clock=stamp_of(now)))
            fleet = self.fleet
            if coordination:
                positions = fleet.positions()
                for i in range(fleet.n):
                    step, pose = int(fleet.progress[i]), pose_message(positions[i], np.zeros((2, 2)), now, MAP_FRAME)
                    self.links[0].send(fleet.steps, lambda i=i, step=step, pose=pose: self.report(i, step, pose))
                return
            self.answered[:] = False
            self.published_at = time.perf_counter()
            for i in range(fleet.n):
                self.poses[i].publish(pose_message(fleet.estimates[i], fleet.covs[i], now, MAP_FRAME, fleet.headings[i]))
            if self.nominal is not None:
                for i, (vx, vy, wz) in enumerate(fleet.nominal()):
                    self.nominal[i].publish(twist_message((vx, vy), wz))

        def report(self, i: int, step: int, pose) -> None:
            """A plan follower's report: its progress and its pose (together lost or late)."""
            self.progress[i].publish(int_message(step))
            self.poses[i].publish(pose)

        def finish(self) -> None:
            """Write the run (``out``) and log how it ended."""
            wall = time.perf_counter() - self.wall_start
            if coordination:
                a, b = self.links
                faults = {"drop": options.drop, "delay": options.delay, "messages_sent": a.sent + b.sent,
                          "messages_dropped": a.dropped + b.dropped, "messages_delayed": a.delayed + b.delayed}
                trace = self.fleet.trace(wall, faults)
            else:
                trace = self.fleet.trace(wall)
            self.get_logger().info(f"stopped after {self.fleet.steps} steps: " + ", ".join(
                f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in trace.results.items()
                if k in ("success", "collisions", "collision_events", "arrived", "finished", "min_pair_distance")))
            if options.out is not None:
                save_trace(trace, options.out)
                self.get_logger().info(f"wrote {options.out}/ {{trace.npz, trace.json}}")

    return SimNode()
