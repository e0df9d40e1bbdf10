"""The navigation pipeline: which stages run for which robot model, and in which order.

Every step, each team's robots go through the stages of :data:`PIPELINES` for their
model, in order; each stage reads and writes one :class:`StepState`. Stages only choose
targets; the last stage, ``keep``, is the model's cell-keeping controller (the safety
layer, one module per model: :func:`~robofleet.avoidance.projection.steer` for single
integrators, :mod:`~robofleet.avoidance.braking` for double integrators,
:mod:`~robofleet.avoidance.diff_drive` for differential drive,
:mod:`~robofleet.avoidance.mpc` for any model under the MPC), which turns the target into
a command that keeps the next state inside the robot's cell. A stage whose block is
switched off (or ``navigation: {enabled: false}``) passes the step on unchanged, which
leaves the paper's controller: the goal, appendix C's recovery and the cell-keeping
controller.

The stages (each its own module, with its design, equations and guarantee):

=================  ==========================================================================
``goal``           :mod:`.goal`: latch arrivals (estimate within the goal tolerance)
``home``           :mod:`.goal`: robots within the tolerance that hold are home
``route``          :mod:`.route`: the roadmap sub-goal and the path length left
``detour``         :mod:`.detour`: blocked robots re-plan around neighbours that hold still
``recovery``       :mod:`.recovery`: appendix C's rotated goal or obstacle vertex
``yielding``       :mod:`.yielding`: arrived robots step aside and return
``project``        the target projected onto the cell, ``Π_Vi(t)`` (single integrators: with the right-hand turn)
``right_hand``     :mod:`.right_hand`: robots a neighbour blocks veer right (single integrators: in ``project``)
``band``           :mod:`.band`: robots deep in an obstacle's band steer back into the cell
``keep``           the model's cell-keeping controller
``progress``       :mod:`robofleet.avoidance.navigation.progress`: which robots are stuck; their recovery starts
=================  ==========================================================================
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..braking import braking_control, braking_rule
from ..cell import Cells
from ..diff_drive import three_projection_control
from ..projection import Projection, project_onto_cells, steer
from .band import out_of_the_band
from .detour import Detours
from .goal import GoalChecker
from .params import NavigationParams
from .progress import DeadlockParams, ProgressChecker
from .recovery import NORMAL, GoalRotation, count_down, recovery_targets, start_recovery
from .right_hand import turned_projection, turned_targets
from .route import Route
from .yielding import HOLD, YIELD, ParkingState, parking_targets

MPC_NO_MPC, MPC_SOLVED, MPC_FALLBACK, MPC_ARRIVED = -1, 0, 1, 2  # mpc_status codes (int8)

PIPELINES: dict[str, tuple[str, ...]] = {
    "single_integrator": ("goal", "route", "detour", "recovery", "yielding", "home", "project", "band", "keep", "progress"),
    "double_integrator": ("goal", "route", "detour", "right_hand", "yielding", "home", "recovery", "keep"),
    "unicycle": ("goal", "route", "yielding", "home", "recovery", "keep"),
    "mpc": ("goal", "home", "keep"),
}
"""The stages of each pipeline, in order. Single integrators recover on the route's target
and turn their projected target (the right-hand rule within the projection stage:
:func:`.right_hand.turned_projection`); double integrators turn the target before their
braking rule projects it, and recover by goal rotation; differential-drive robots take neither
the right-hand turn nor detours (their three-projection controller drives the turned arcs
into the walls). Single integrators find their stuck robots with the progress checker
(:class:`.progress.ProgressChecker`, on the route's path length left), which the safety
filter shares; double integrators and unicycles keep appendix C's net displacement
(:class:`.recovery.GoalRotation`): on the path length left, unicycles turning in place and
double integrators accelerating read as stuck (docs/results/avoidance.md "One progress
checker"). The MPC (any model with ``controller: mpc``) runs appendix C's rotation
inside its own controller and no navigation stage."""


def pipeline_of(kind: str, controller: str) -> str:
    """The :data:`PIPELINES` key of a team: ``mpc`` for any model under the MPC, else its model."""
    return "mpc" if controller == "mpc" else kind


@dataclass
class StepState:
    """What the stages of one team read and write during one step.

    ``p`` the estimates ``(n, d)``, ``goals``, ``cells``; the stages fill in ``target``
    (where to go), ``to_go`` (the path length left), ``proj`` (the projected target),
    ``moving`` (arrived robots that move this step), ``u`` (the command), ``move_dist`` and
    ``empty`` (robots whose cell was empty; ``None`` when the keeper does not find out)."""

    p: np.ndarray
    goals: np.ndarray
    cells: Cells
    state: np.ndarray  # the team's TRUE states with the estimated position
    target: np.ndarray = None
    to_go: np.ndarray = None
    proj: Projection | None = None
    moving: np.ndarray = None
    u: np.ndarray = None
    move_dist: np.ndarray = None
    empty: np.ndarray | None = None
    route_target: np.ndarray = None  # the target before appendix C's recovery changed it


@dataclass
class TeamNavigation:
    """One team's navigation: its pipeline, its stages' parameters and every robot's memory
    (a robot keeps only its own; the still trackers compute what every neighbour sees)."""

    pipeline: str
    params: NavigationParams
    deadlock: DeadlockParams
    n: int
    v_max: float
    dt: float
    tolerance: float
    local_box: float
    sigma: float = 0.0
    route: Route | None = None
    detours: Detours | None = None
    grown: np.ndarray | None = field(default=None, repr=False)  # appendix C vertex targets (single integrators)
    keeper: object = None  # the model's cell-keeping controller's parameters, or the MPC
    goal: GoalChecker = None
    parking: ParkingState | None = None
    rotation: GoalRotation | None = None
    mode: np.ndarray = None
    mode_left: np.ndarray = None
    vertex: np.ndarray = None
    progress: ProgressChecker = None
    fallback_steps: int = 0  # MPC robot-steps that fell back, and that were solved
    solve_steps: int = 0
    mpc_status: np.ndarray = None
    stages: list = field(default=None, repr=False)

    def __post_init__(self):
        self.stages = [STAGES.get((name, self.pipeline), STAGES.get(name)) for name in PIPELINES[self.pipeline]]
        self.mpc_status = np.full(self.n, MPC_NO_MPC, np.int8)
        n = self.n
        self.goal = GoalChecker.initial(n, self.tolerance)
        self.mode, self.mode_left, self.vertex = np.zeros(n, np.int8), np.zeros(n, np.int32), np.zeros((n, 2))
        self.progress = ProgressChecker(self.deadlock, n, self.v_max, self.dt)
        if self.params.enabled and self.pipeline != "mpc":
            self.parking = ParkingState.initial(n)
        if self.pipeline in ("double_integrator", "unicycle"):
            d = self.deadlock
            self.rotation = GoalRotation(n, d.window, d.progress_fraction * self.v_max * d.window * self.dt, d.recover_steps)

    @property
    def arrived(self) -> np.ndarray:
        """Latched arrivals (:class:`.goal.GoalChecker`)."""
        return self.goal.arrived

    @property
    def navigating(self) -> bool:
        """Whether the navigation stages run for this team."""
        return self.params.enabled and self.pipeline != "mpc"

    def yielding_params(self):
        """The yielding block as this model uses it: models whose blocked robots come to
        rest cannot tell a parked neighbour by its holding still (still radius 0)."""
        y = self.params.yielding
        return y if self.pipeline == "single_integrator" else replace(y, still_radius=0.0)

    def deadlock_counts(self) -> np.ndarray:
        """Deadlock detections per robot so far."""
        if self.pipeline == "mpc":
            return self.keeper.deadlocks
        return self.rotation.deadlocks if self.rotation is not None else self.progress.deadlocks

    @property
    def livelock_count(self) -> np.ndarray:
        """Of the deadlock detections, those classed as livelocks (single integrators)."""
        return self.progress.livelock_count

    def command(self, p: np.ndarray, goals: np.ndarray, cells: Cells, state: np.ndarray | None = None) -> StepState:
        """One step of the pipeline from the estimates ``p``, the goals and the cells (and
        the team's states with the estimated positions, for models with more than a
        position); the command is the result's ``u``."""
        step = StepState(p, goals, cells, p if state is None else state)
        self.decide(step)
        return step

    def decide(self, s: StepState) -> None:
        """Run the team's pipeline on one step."""
        for stage in self.stages:
            stage(self, s)


# ---------------------------------------------------------------------------------------
# the stages
# ---------------------------------------------------------------------------------------
def goal_stage(t: TeamNavigation, s: StepState) -> None:
    """Latch arrivals; the target is the goal, the distance left the straight one."""
    t.goal.observe(s.p, s.goals)
    s.target, s.to_go, s.moving = s.goals, t.goal.distance, np.zeros(len(s.goals), bool)


def home_stage(t: TeamNavigation, s: StepState) -> None:
    """Robots within the tolerance that hold (not yielding or returning) are home."""
    t.goal.settle(True if t.parking is None else t.parking.mode == HOLD)


def route_stage(t: TeamNavigation, s: StepState) -> None:
    """The roadmap's sub-goal and path length left (without a route: the goal stage's)."""
    if t.navigating and t.route is not None:
        s.target, s.to_go = t.route.step(s.p)


def detour_stage(t: TeamNavigation, s: StepState) -> None:
    if t.navigating and t.detours is not None and t.route is not None:
        s.target, s.to_go = t.detours.apply(s.p, t.arrived, s.target, s.to_go)


def single_integrator_recovery(t: TeamNavigation, s: StepState) -> None:
    """Steer to the rotated target or the obstacle vertex while recovering (recovery starts in ``progress``)."""
    s.route_target = s.target
    s.target = recovery_targets(s.p, s.target, t.mode, t.vertex)


def rotation_recovery(t: TeamNavigation, s: StepState) -> None:
    """Appendix C's detection and rotation on the net displacement (:class:`.recovery.GoalRotation`)."""
    s.target = t.rotation.working_goals(s.p, s.target, t.arrived)


def yielding_stage(t: TeamNavigation, s: StepState) -> None:
    """Arrived robots step aside or hold (:func:`.yielding.parking_targets`); a robot on its
    way back — returning from a yield, or holding away from its goal without being home
    (:class:`.goal.GoalChecker`) — follows the route's target, as a robot on its way does."""
    if not (t.navigating and t.params.yielding.enabled):
        return
    parked, s.moving = parking_targets(s.p, s.goals, t.arrived, t.parking, t.yielding_params(), t.local_box, t.tolerance)
    if not t.arrived.any():  # nobody parked: every target stays, nobody moves
        return
    s.moving |= t.arrived & (t.parking.mode == HOLD) & ~t.goal.home & ~t.goal.within
    returning = s.moving & (t.parking.mode != YIELD)
    s.target = np.where((t.arrived & ~returning)[:, None], parked, s.target)


def project_stage(t: TeamNavigation, s: StepState) -> None:
    """``Π_Vi(t)``; with the right-hand rule on, the turned targets of the blocked robots
    that drive (not arrived, not recovering) in the same pass (:func:`.right_hand.turned_projection`)."""
    if t.navigating and t.params.right_hand.angle > 0:
        s.proj = turned_projection(s.p, s.target, s.cells, ~t.arrived & (t.mode == NORMAL), t.params.right_hand)
    else:
        s.proj = project_onto_cells(s.target, s.cells)


def right_hand_stage(t: TeamNavigation, s: StepState) -> None:
    if t.navigating:
        s.target = turned_targets(s.p, s.target, s.cells, ~t.arrived, t.params.right_hand)


def band_stage(t: TeamNavigation, s: StepState) -> None:
    if t.navigating and t.sigma > 0:
        s.proj = out_of_the_band(s.p, s.proj, s.cells, t.params.band.sigmas * t.sigma)


def progress_stage(t: TeamNavigation, s: StepState) -> None:
    """Which robots are stuck on their way (:class:`.progress.ProgressChecker` on the path
    length left); their recovery starts (the obstacle branch only without a route), and
    every recovery counts down."""
    sitting = s.move_dist < 1e-9  # projected target at the estimate (an empty cell passes inf)
    stuck = t.progress.observe(s.to_go, ~t.arrived & (t.mode == NORMAL), sitting)
    if stuck.any():
        grown = t.grown if not (t.navigating and t.route is not None) else None  # the roadmap already routes around obstacles
        start_recovery(stuck, s.p, s.route_target, s.cells, s.proj.active, t.mode, t.mode_left, t.vertex, t.deadlock, grown)
    count_down(s.p, t.mode, t.mode_left, t.vertex, max(t.tolerance, float(np.max(t.v_max)) * t.dt))


# -- the cell-keeping controllers ---------------------------------------------------------
def keep_single_integrator(t: TeamNavigation, s: StepState) -> None:
    """The one-step controller (appendix C): toward the projected target at most ``v_max``."""
    hold = t.arrived & ~s.moving
    s.u, speed, s.move_dist = steer(s.p, s.proj, t.v_max, t.dt, hold)
    t.progress.record_speed(speed)
    s.empty = s.proj.empty


def keep_double_integrator(t: TeamNavigation, s: StepState) -> None:
    """The braking rule (Sec. 5.2) toward the projected target; holding robots brake."""
    proj = project_onto_cells(s.target, s.cells)
    target = np.where(proj.empty[:, None], s.p, proj.point)
    velocity, params = s.state[:, 2:], t.keeper
    u, _ = braking_rule(s.p, velocity, target, s.cells.A, s.cells.b, s.cells.valid, params, t.dt)
    s.u = np.where((t.arrived & ~s.moving)[:, None], braking_control(velocity, params.a_max, t.dt), u)
    s.empty = proj.empty


def keep_unicycle(t: TeamNavigation, s: StepState) -> None:
    """Three projections (Sec. 5.3); holding robots stop."""
    u = three_projection_control(s.state, s.target, s.cells.A, s.cells.b, s.cells.valid, t.keeper, t.dt, project=project_2d)
    s.u = np.where((t.arrived & ~s.moving)[:, None], 0.0, u)


def keep_mpc(t: TeamNavigation, s: StepState) -> None:
    """The B-UAVC MPC (Sec. 5.4; appendix C's rotation inside), with its solve counts."""
    s.u, info = t.keeper.control(s.state, s.goals, s.cells.A, s.cells.b, s.cells.valid, arrived=t.arrived)
    t.fallback_steps += int(info["fallback"].sum())
    t.solve_steps += int((~t.arrived).sum())
    t.mpc_status = np.where(t.arrived, MPC_ARRIVED, np.where(info["fallback"], MPC_FALLBACK, MPC_SOLVED))


def project_2d(points: np.ndarray, A: np.ndarray, b: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact projection onto 2-D cells in the ``(points, A, b, valid) -> (proj, ok)`` form
    :func:`~robofleet.avoidance.diff_drive.three_projection_control` takes."""
    proj = project_onto_cells(points, Cells(A, b, valid, np.zeros(valid.shape, np.int8), np.zeros(valid.shape, np.intp)))
    return np.where(proj.empty[:, None], points, proj.point), ~proj.empty


STAGES = {
    "goal": goal_stage, "home": home_stage, "route": route_stage, "detour": detour_stage, "yielding": yielding_stage, "project": project_stage,
    "band": band_stage, "progress": progress_stage,
    ("recovery", "single_integrator"): single_integrator_recovery, "recovery": rotation_recovery,
    "right_hand": right_hand_stage,
    ("keep", "single_integrator"): keep_single_integrator, ("keep", "double_integrator"): keep_double_integrator,
    ("keep", "unicycle"): keep_unicycle, ("keep", "mpc"): keep_mpc,
}
"""Each stage's function: by ``(stage, pipeline)`` where a model has its own form, else by ``stage``."""
