"""The B-UAVC safety filter as a ROS 2 node, shaped like Nav2's collision monitor.

For each robot it serves, the node takes the desired velocity on ``<ns>/cmd_vel_nav``
and publishes, right away, the filtered one on ``<ns>/cmd_vel``: the velocity that
:meth:`RobotSafetyFilter.filter <robofleet.avoidance.safety_filter.RobotSafetyFilter.filter>`
returns for the robot's latest pose, every other robot's latest pose (each robot's
``<ns>/pose``), the walls and the static obstacles (Zhu, Brito & Alonso-Mora 2022, Sec. 4:
the next estimate ``p̂ + u Δt`` stays in the robot's buffered uncertainty-aware Voronoi
cell). With it goes the premise flag (``<ns>/safety_state``: ``estimate_in_cell``,
``estimate_outside_cell``, ``empty_cell``, ``recovering``, ``pose_stale``, ``no_pose``,
``error``); every ``dt`` the cells computed since are published as polygons
(``<ns>/cell``, ``PolygonStamped``) and all cells as markers on ``/robofleet/cells``. One node serves the fleet; ``robot=K`` serves robot K alone (one
node per robot: the decentralized deployment; it still reads every robot's pose).

Old poses (the rules, and why they keep the bound)
    *Own pose.* A robot whose own latest pose is older than ``pose_timeout`` (by the
    node's clock) gets zero velocity: it holds still until it is localised again.

    *Poses of different ages.* Poses are taken at their header stamps. Let ``t_ref`` be
    the later of the node's time now (``/clock`` with ``use_sim_time``) and the newest
    stamp held; robot ``j``'s pose is ``τ_j = t_ref − stamp_j`` old, and robot ``j`` (speed
    at most ``v_max,j``) may have moved up to ``D_j = v_max,j · τ_j`` since it was taken.
    Robot ``j`` stays in every cell computation at its last estimate ``p̂_j`` with its
    covariance grown to

        ``Σ'_j = Σ_j + c_j I``,  ``c_j = (D_j/q)² + 2 (D_j/q) √λ_max(Σ_j)``,  ``q = Φ⁻¹(√(1 − δ))``

    (:func:`grown_covariance`). For every unit direction ``a``,
    ``q √(aᵀ Σ'_j a) ≥ q √(aᵀ Σ_j a) + D_j`` (square both sides: ``c_j ≥ 2 (D_j/q)
    √(aᵀΣ_j a) + (D_j/q)²`` since ``aᵀ Σ_j a ≤ λ_max``). The true position is ``p̂_j + e + d``
    with ``e ~ N(0, Σ_j)`` and ``‖d‖ ≤ D_j``, so ``aᵀ(e + d) ≤ q √(aᵀ Σ'_j a)`` whenever
    ``aᵀ e ≤ q √(aᵀ Σ_j a)``, an event of probability ``√(1 − δ)``: along every separator
    normal the true position stays inside the buffer built from ``Σ'_j`` with at least
    the probability the bound of Sec. 4 (Eq. 13, buffer ``β = r_s + q √(aᵀ Σ a)``) uses.
    The same ``Σ'_j`` serves robot ``j`` as ego (its command moves it from where it
    truly is, ``p̂_j + e + d``, so its own grown buffer keeps ``p̂_j + u Δt + e + d`` on its
    side) and as everybody's neighbour; within one computation all robots share
    ``t_ref``, so two robots filtered together build their separators from the same
    numbers (reciprocity, appendix B) and the pair bound holds as in-process. When every
    pose is stamped now (the simulator with ``use_sim_time``), nothing is grown and the
    commands are exactly those of :class:`~robofleet.avoidance.safety_filter.SafetyFilter`.

    Commands that arrive together (one period of the simulator, or of a planner serving
    the fleet) are filtered together, after the poses that arrived with them
    (:meth:`filter_pending` runs once the executor has read them). What remains assumed:
    a robot whose pose has stopped arriving obeys the zero command it is sent after
    ``pose_timeout`` (so it moves at most ``v_max · (pose_timeout + Δt)`` from its last
    pose), and a robot filtered at another time than its neighbour (commands that arrive
    apart) sees the neighbour's pose grown for the time between: safe for that robot's
    side, though the two separators then differ by the growth.

Robots without any pose yet are not in the cells (the node has no position for them;
the closed loop starts once every robot has published).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal, Optional

import numpy as np
from pydantic import Field

from ..avoidance.buffer import confidence_quantile
from ..avoidance.safety_filter import DEFAULT_DEADLOCK, RobotSafetyFilter, SafetyFilter
from ..core.config import SpecModel, read_mapping, validate_model
from ..core.errors import ConfigError, RobofleetError, ScenarioError, short_repr
from ..scenarios import load_scenario
from .messages import MessageError, cell_markers, polygon_message, read_pose, read_twist, rotate, string_message, twist_message
from .runtime import (CELLS_TOPIC, DEFAULT_PREFIX, MAP_FRAME, BadInputLog, checked_frame, checked_prefix, robot_of_topic,
                      robot_topic, stream_qos, wall_clock)

POSE_TIMEOUT_STEPS = 5
"""Default ``pose_timeout``: this many control steps ``dt``."""


# ---------------------------------------------------------------------------------------
# settings: from a scenario or a ros__parameters file
# ---------------------------------------------------------------------------------------
class FilterParameters(SpecModel):
    """The ``ros__parameters`` of a filter node (docs/ros2.md shows a file)."""

    robots: int = Field(ge=1, le=100_000, description="fleet size: robots robot0 … robot{N-1}")
    radius: float = Field(gt=0, description="safety radius r_s [m]")
    v_max: float = Field(gt=0, description="speed limit [m/s]")
    dt: float = Field(gt=0, description="control period Δt [s]")
    delta: float = Field(default=0.1, gt=0, lt=0.75, description="collision threshold δ of the chance constraint")
    local_box: float = Field(default=2.0, gt=0, description="half-width R_loc of the box of neighbours considered [m]")
    bounds: Optional[list[float]] = Field(default=None, min_length=4, max_length=4, description="xmin, ymin, xmax, ymax")
    obstacles: list[float] = Field(default_factory=list, description="x0, y0, x1, y1, … of every obstacle, one after the other")
    obstacle_vertex_counts: list[int] = Field(default_factory=list, description="vertices of each obstacle in `obstacles`")
    obstacle_sigma: float = Field(default=0.0, ge=0, description="σ of the obstacles' positions [m]")
    prefix: str = DEFAULT_PREFIX
    pose_timeout: Optional[float] = Field(default=None, gt=0, description="own pose older than this: zero velocity [s]")
    velocity_frame: Literal["map", "base"] = "map"
    deadlock_memory: bool = True

    def obstacle_polygons(self) -> list[np.ndarray]:
        counts, flat = self.obstacle_vertex_counts, np.asarray(self.obstacles, float)
        if any(c < 3 for c in counts) or 2 * sum(counts) != len(flat):
            raise ScenarioError("obstacle_vertex_counts", f"counts of at least 3 whose sum is half the {len(flat)} numbers of obstacles",
                                counts, source=self.source)
        ends = 2 * np.cumsum(counts)
        return [flat[e - 2 * c: e].reshape(-1, 2) for c, e in zip(counts, ends)]


@dataclass
class FilterSettings:
    """Everything a filter node needs: one :class:`RobotSafetyFilter` per robot of the
    fleet, the speed limits (for the staleness rule) and the topic conventions."""

    filters: list[RobotSafetyFilter]
    v_max: np.ndarray
    quantile: float
    dt: float
    local_box: float
    prefix: str = DEFAULT_PREFIX
    velocity_frame: str = "map"
    pose_timeout: float = 0.5
    source: str = ""

    @property
    def n(self) -> int:
        return len(self.filters)


def is_parameter_file(ref: str) -> bool:
    """Whether ``ref`` is a YAML file holding ``<node>: {ros__parameters: …}``."""
    path = Path(ref)
    if path.suffix not in (".yaml", ".yml") or not path.is_file():
        return False
    data = read_mapping(path)[0]
    return any(isinstance(v, dict) and "ros__parameters" in v for v in data.values())


def settings_from(ref: str, overrides: dict | None = None, *, prefix: str | None = None, velocity_frame: str | None = None,
                  pose_timeout: float | None = None, deadlock_memory: bool = True) -> FilterSettings:
    """The settings of a filter node from a scenario (name or file, with ``overrides``) or a
    ``ros__parameters`` file; explicit arguments win over the file's values."""
    if is_parameter_file(ref):
        if overrides:
            raise ConfigError(f"--set: expected no overrides with a parameter file, received {short_repr(overrides)} for {ref}")
        settings = settings_from_parameters(ref)
    else:
        settings = settings_from_scenario(ref, overrides, deadlock_memory)
    if prefix is not None:
        settings.prefix = checked_prefix(prefix)
    if velocity_frame is not None:
        settings.velocity_frame = checked_frame(velocity_frame)
    if pose_timeout is not None:
        if not pose_timeout > 0:
            raise ConfigError(f"--pose-timeout: expected a number of seconds > 0, received {short_repr(pose_timeout)}")
        settings.pose_timeout = float(pose_timeout)
    return settings


def settings_from_scenario(ref: str, overrides: dict | None, deadlock_memory: bool = True) -> FilterSettings:
    """From a 2-D single-integrator avoidance scenario: its r_s, v_max per team, δ, Δt,
    R_loc, walls and obstacles (:meth:`RobotSafetyFilter.from_spec`)."""
    spec = load_scenario(ref, overrides)
    if getattr(spec, "family", None) != "avoidance":
        raise ConfigError(f"SCENARIO: expected an avoidance scenario or a ros__parameters file, received a {spec.family} scenario ({ref})")
    fleet = SafetyFilter.from_spec(spec)
    deadlock = DEFAULT_DEADLOCK if deadlock_memory else None
    filters = [RobotSafetyFilter.from_spec(spec, i, deadlock=deadlock) for i in range(fleet.n)]
    return FilterSettings(filters, fleet.v_max, fleet.model.quantile, fleet.dt, float(spec.local_box),
                          pose_timeout=POSE_TIMEOUT_STEPS * fleet.dt, source=str(spec.source or ref))


def settings_from_parameters(path: str) -> FilterSettings:
    """From a ``ros__parameters`` file (:class:`FilterParameters`)."""
    data, source = read_mapping(path)
    node, = [k for k, v in data.items() if isinstance(v, dict) and "ros__parameters" in v][:1] or [None]
    params = validate_model(FilterParameters, data[node]["ros__parameters"] or {}, source)
    params._source = f"{source}: {node}.ros__parameters"
    cov = params.obstacle_sigma ** 2 * np.eye(2)
    try:
        filters = [RobotSafetyFilter.create(radius=params.radius, dt=params.dt, v_max=params.v_max, delta=params.delta,
                                            bounds=params.bounds, obstacles=params.obstacle_polygons(), obstacle_cov=cov,
                                            local_box=params.local_box, deadlock=DEFAULT_DEADLOCK if params.deadlock_memory else None)
                   for _ in range(params.robots)]
    except ConfigError as exc:
        raise ConfigError(f"{source}: {node}.ros__parameters: {exc}") from None
    return FilterSettings(filters, np.full(params.robots, params.v_max), confidence_quantile(params.delta), params.dt, params.local_box,
                          checked_prefix(params.prefix, f"{source}: prefix"), params.velocity_frame,
                          params.pose_timeout or POSE_TIMEOUT_STEPS * params.dt, source=source or path)


# ---------------------------------------------------------------------------------------
# the fleet as the node sees it, and one robot's filtering
# ---------------------------------------------------------------------------------------
def grown_covariance(cov: np.ndarray, reach: np.ndarray, quantile: float) -> np.ndarray:
    """``Σ + c I`` with ``c = (D/q)² + 2 (D/q) √λ_max(Σ)`` per robot (``cov (n, 2, 2)``,
    ``reach = D (n,)``): for every unit ``a``, ``q √(aᵀ Σ' a) ≥ q √(aᵀ Σ a) + D`` (see the
    module docstring); ``D = 0`` leaves ``Σ`` unchanged."""
    if not quantile > 0:
        raise ConfigError(f"delta: expected δ < 0.75 (a positive quantile Φ⁻¹(√(1 − δ))), received quantile {quantile!r}")
    ratio = np.asarray(reach, float) / quantile
    largest = np.sqrt(np.maximum(np.linalg.eigvalsh(cov)[:, -1], 0.0))
    c = ratio ** 2 + 2 * ratio * largest
    return cov + c[:, None, None] * np.eye(2)


class FleetView:
    """Every robot's latest pose (position, x–y covariance, stamp, yaw); a pose older than
    the one held (a late message) is dropped."""

    def __init__(self, n: int):
        self.positions = np.full((n, 2), np.nan)
        self.covs = np.zeros((n, 2, 2))
        self.stamps = np.full(n, -np.inf)
        self.yaws = np.zeros(n)

    @property
    def known(self) -> np.ndarray:
        return np.isfinite(self.stamps)

    def update(self, robot: int, position: np.ndarray, cov: np.ndarray, stamp: float, yaw: float) -> bool:
        """Hold this pose unless an equally new or newer one is held; returns whether it was taken."""
        if stamp < self.stamps[robot]:
            return False
        self.positions[robot], self.covs[robot], self.stamps[robot], self.yaws[robot] = position, cov, stamp, yaw
        return True

    def covariances(self, v_max: np.ndarray, quantile: float, now: float) -> np.ndarray:
        """The covariances the cells use: each grown by ``v_max · (t_ref − stamp)``, ``t_ref``
        the later of ``now`` and the newest stamp held (:func:`grown_covariance`)."""
        known = self.known
        covs = self.covs.copy()
        if known.any():
            age = max(now, self.stamps[known].max()) - self.stamps[known]
            covs[known] = grown_covariance(self.covs[known], v_max[known] * age, quantile)
        return covs


@dataclass(frozen=True)
class Filtered:
    """One robot's answer: the velocity (map frame), its safety state and its cell
    ``{p : A p ≤ b}`` (``A (m, 2)``, ``b (m,)``; ``None`` without one)."""

    velocity: np.ndarray
    state: str
    cell: tuple[np.ndarray, np.ndarray] | None


def filter_robot(settings: FilterSettings, view: FleetView, robot: int, desired: np.ndarray, now: float) -> Filtered:
    """Robot ``robot``'s filtered velocity (map frame) for ``desired`` (map frame) at time ``now``."""
    if not view.known[robot]:
        return Filtered(np.zeros(2), "no_pose", None)
    if now - view.stamps[robot] > settings.pose_timeout:
        return Filtered(np.zeros(2), "pose_stale", None)
    covs = view.covariances(settings.v_max, settings.quantile, now)
    others = view.known.copy()
    others[robot] = False
    result = settings.filters[robot].filter(view.positions[robot], covs[robot], desired, view.positions[others], covs[others])
    state = ("empty_cell" if result.empty[0] else "recovering" if result.recovering[0]
             else "estimate_in_cell" if result.estimate_in_cell[0] else "estimate_outside_cell")
    valid = result.cells.valid[0]
    return Filtered(result.velocity[0], state, (result.cells.A[0][valid], result.cells.b[0][valid]))


def cell_vertices(cells: dict[int, tuple[np.ndarray, np.ndarray]], positions: np.ndarray, half_width: float) -> dict[int, np.ndarray]:
    """Each cell ``{p : A p ≤ b}`` as polygon vertices (counter-clockwise), clipped to the
    box ``half_width`` around all robots, computed together (:func:`~robofleet.viz.avoidance_geometry.cell_polygons`)."""
    from ..viz.avoidance_geometry import cell_polygons

    if not cells:
        return {}
    robots = sorted(cells)
    m = max(max(len(cells[i][1]) for i in robots), 1)
    A, b = np.zeros((len(robots), m, 2)), np.ones((len(robots), m))
    for k, i in enumerate(robots):
        A[k, : len(cells[i][1])], b[k, : len(cells[i][1])] = cells[i]
    known = positions[np.all(np.isfinite(positions), axis=1)]
    lo, hi = known.min(axis=0) - half_width, known.max(axis=0) + half_width
    clip = np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])
    counts, vertices = cell_polygons(A, b, clip)
    ends = np.cumsum(counts)
    return {i: vertices[e - c: e] for i, c, e in zip(robots, counts, ends)}


# ---------------------------------------------------------------------------------------
# the node
# ---------------------------------------------------------------------------------------
def make_filter_node(settings: FilterSettings, robot: int | None = None, use_sim_time: bool = False, name: str | None = None):
    """The filter node for the whole fleet (``robot=None``) or for robot ``robot`` alone."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from geometry_msgs.msg import PolygonStamped, PoseWithCovarianceStamped, Twist
    from std_msgs.msg import String
    from visualization_msgs.msg import MarkerArray

    if robot is not None and (isinstance(robot, bool) or not isinstance(robot, int) or not 0 <= robot < settings.n):
        raise ConfigError(f"--robot: expected a robot index in 0..{settings.n - 1}, received {short_repr(robot)}")
    served = list(range(settings.n)) if robot is None else [robot]

    class FilterNode(Node):
        def __init__(self) -> None:
            super().__init__(name or ("robofleet_filter" if robot is None else f"robofleet_filter_{robot}"),
                             parameter_overrides=[Parameter("use_sim_time", value=use_sim_time)])
            self.view = FleetView(settings.n)
            self.bad = BadInputLog(self.get_logger())
            self.cells: dict[int, tuple[np.ndarray, np.ndarray]] = {}
            self.polygons: dict[int, np.ndarray] = {}
            self.unknown_reported: set[str] = set()
            p, qos = settings.prefix, stream_qos()
            for i in range(settings.n):
                self.create_subscription(PoseWithCovarianceStamped, robot_topic(p, i, "pose"), lambda m, i=i: self.on_pose(i, m), qos)
            self.out = {}
            for i in served:
                self.out[i] = (self.create_publisher(Twist, robot_topic(p, i, "cmd_vel"), qos),
                               self.create_publisher(PolygonStamped, robot_topic(p, i, "cell"), qos),
                               self.create_publisher(String, robot_topic(p, i, "safety_state"), qos))
                self.create_subscription(Twist, robot_topic(p, i, "cmd_vel_nav"), lambda m, i=i: self.on_command(i, m), qos)
            self.markers = self.create_publisher(MarkerArray, CELLS_TOPIC, qos)
            self.pending: dict[int, np.ndarray] = {}
            self.flush = self.create_guard_condition(self.filter_pending)
            self.create_timer(settings.dt, self.publish_cells)
            self.create_timer(2.0, self.report_unknown_robots, clock=wall_clock())
            self.filtered = 0
            self.get_logger().info(f"filtering {len(served)} of {settings.n} robots ({settings.source}), "
                                   f"{settings.prefix}K/cmd_vel_nav -> {settings.prefix}K/cmd_vel")

        def now(self) -> float:
            return self.get_clock().now().nanoseconds * 1e-9

        def on_pose(self, i: int, msg) -> None:
            try:
                position, cov, stamp, yaw = read_pose(msg, MAP_FRAME)
            except MessageError as exc:
                self.bad(robot_topic(settings.prefix, i, "pose"), str(exc))
                return
            self.view.update(i, position, cov, stamp, yaw)

        def on_command(self, i: int, msg) -> None:
            """Hold the command until the messages that arrived with it are read (a guard
            condition runs :meth:`filter_pending` after them): a burst of poses and
            commands is filtered from the poses of the same burst."""
            try:
                self.pending[i] = read_twist(msg)[0]
            except MessageError as exc:
                self.bad(robot_topic(settings.prefix, i, "cmd_vel_nav"), str(exc))
                return
            self.flush.trigger()

        def filter_pending(self) -> None:
            pending, self.pending = self.pending, {}
            for i, linear in pending.items():
                self.answer(i, linear)

        def answer(self, i: int, linear: np.ndarray) -> None:
            topic = robot_topic(settings.prefix, i, "cmd_vel_nav")
            base = settings.velocity_frame == "base"
            desired = rotate(linear, self.view.yaws[i]) if base else linear
            try:
                answer = filter_robot(settings, self.view, i, desired, self.now())
            except RobofleetError as exc:  # e.g. two robots reporting the same position
                self.bad(topic, f"cannot filter ({exc}), zero velocity sent")
                answer = Filtered(np.zeros(2), "error", None)
            velocity = rotate(answer.velocity, -self.view.yaws[i]) if base else answer.velocity
            cmd, _, state = self.out[i]
            cmd.publish(twist_message(velocity))
            self.filtered += 1
            state.publish(string_message(answer.state))
            if answer.cell is not None:
                self.cells[i] = answer.cell

        def publish_cells(self) -> None:
            """Every ``dt``: the cells computed since the last time, as polygons and markers."""
            if not self.cells:
                return
            now = self.now()
            fresh = cell_vertices(self.cells, self.view.positions, settings.local_box)
            self.cells = {}
            for i, vertices in fresh.items():
                self.out[i][1].publish(polygon_message(vertices, now, MAP_FRAME))
            self.polygons.update(fresh)
            self.markers.publish(cell_markers(self.polygons, now, MAP_FRAME, lifetime=max(1.0, 5 * settings.dt)))

        def report_unknown_robots(self) -> None:
            """One log line per topic of a robot outside the fleet (its messages are not read)."""
            for topic, _ in self.get_topic_names_and_types():
                k = robot_of_topic(settings.prefix, topic)
                if k is not None and k >= settings.n and topic not in self.unknown_reported:
                    self.unknown_reported.add(topic)
                    self.get_logger().warning(f"{topic}: robot {k} is not in the fleet {settings.prefix}0..{settings.prefix}{settings.n - 1}; "
                                              f"its messages are ignored")

    return FilterNode()
