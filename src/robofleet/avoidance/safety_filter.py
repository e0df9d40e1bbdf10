"""B-UAVC as a safety filter for velocities from any source (a planner, a learned policy,
a joystick): Zhu, Brito & Alonso-Mora 2022, Sec. 4 (the cell), used as a one-step filter.

What it computes (single integrator ``p⁺ = p + u Δt``)
    For robot ``i`` with estimate ``p̂_i``, covariance ``Σ_i`` and desired velocity
    ``u_des``, the B-UAVC ``V_i`` is built from the current estimates (Eq. 13 with the
    separators of appendix B, the buffers ``β`` and the ε-shadows of appendix A; only
    neighbours and obstacles inside ``p̂_i ± R_loc``). The filter returns

        ``u = (Π_Vi(p̂_i + sat(u_des) Δt) − p̂_i) / Δt``,  ``sat(u) = u · min(1, v_max / ‖u‖)``,

    i.e. the velocity closest to ``sat(u_des)`` among those whose next estimate
    ``p̂_i + u Δt`` lies in ``V_i`` (exact projection onto the convex cell,
    :func:`~.projection.project_onto_cells`). Projection onto a convex set is
    non-expansive and fixes ``p̂_i ∈ V_i``, so ``‖u‖ ≤ ‖sat(u_des)‖ ≤ v_max``: the speed
    limit needs no second step, and ``u = sat(u_des)`` whenever that already keeps the
    robot in its cell (minimal intervention). The straight step from ``p̂_i`` to
    ``p̂_i + u Δt`` stays in ``V_i`` (convexity).

The guarantee (Sec. 4), and what it assumes
    If (1) every robot's true position is ``N(p̂_i, Σ_i)`` with the ``Σ_i`` given, the
    errors of different robots independent; (2) every robot filters with the same
    estimates of its neighbours (reciprocity of the separators, appendix B), the same
    ``δ`` and ``R_loc``, and its neighbours' true radii; (3) the obstacles are convex
    polygons displaced by ``N(0, Σ_o)``; (4) the estimate lies in its own cell when the
    cell is built (``estimate_in_cell``); (5) the robot executes ``u`` as a single
    integrator for ``Δt`` (its next estimate is ``p̂_i + u Δt`` with the same ``Σ_i``) —
    then, at the next step, each pair of robots inside each other's local box is closer
    than ``r_i + r_j`` with probability at most ``δ`` (radii and covariances may differ
    from robot to robot: each pair's row keeps the mean radius ``(r_i + r_j)/2`` and the
    robot's own buffer, :mod:`.cell`), and each robot is within ``r_i`` of an obstacle
    with probability at most ``δ``. It is a bound per pair and per step, not per run; it
    says nothing about robots outside ``R_loc`` of each other that come within
    ``r_i + r_j`` in one step (choose ``R_loc ≥ 2 r_max + 2 v_max Δt`` plus a few σ); it
    covers no deadlock.

    With exact estimates (Σ = 0) no premise about the cells is needed for the robots:
    pairs that start at least ``r_i + r_j`` apart stay so at every step, whatever the
    desired velocities, even when a cell is empty or a robot sits at a wall (the
    invariant of :mod:`.cell`: every filtered step ends on a segment from the estimate
    to a point of its cell, or holds still).

Numbers
    Any finite desired velocity is accepted (``1e200`` m/s keeps its direction at
    ``v_max``); estimates may be ``1e-300`` apart or ``1e20`` m away, covariances up to
    ``1e300`` m² (the separators work on power-of-two scaled differences,
    :mod:`.separator`; estimates farther apart than the neighbour grid can index use a
    k-d tree). Coordinates, radii, ``v_max`` and the step ``v_max Δt`` are at most
    :data:`MAX_LENGTH`; larger values, booleans, complex numbers, wrong shapes and
    degenerate polygons (fewer than 3 distinct vertices, no area, not convex, bounds
    without room for the largest robot) are a one-line
    :class:`~robofleet.core.errors.ConfigError` naming the argument.

When the premise fails (documented choices)
    * Estimate outside its own cell (noise, or a neighbour closer than the buffers): the
      filter heads for ``Π_Vi(p̂_i + sat(u_des) Δt)``, the cell point it would have gone to,
      at speed at most ``v_max`` (the step is shortened along the same direction). The
      distance of the next estimate to the cell then shrinks (distance to a convex set
      is convex along the segment and 0 at its end), but the bound does not apply to
      that step. ``estimate_in_cell`` is ``False``.
    * Empty cell (the constraints exclude every point): the filter returns ``u = 0`` (the
      robot holds still; nothing better is safe by the cell) and ``empty`` is ``True``.

Robot models
    The filter is exact for **single integrators** (velocity-controlled holonomic robots)
    in 2-D. A differential-drive or double-integrator robot may track ``u`` with its own
    low-level controller, but then the step is no longer a straight segment of length
    ``‖u‖ Δt`` and the guarantee does not carry over; for those models use the closed
    loops of :mod:`robofleet.avoidance.simulation` (three projections, Sec. 5.3; the braking rule, Sec. 5.2;
    the MPC, Sec. 5.4). 3-D cells are not filtered here.

Deadlock memory (appendix C, in velocity form)
    The navigation's progress checker (:class:`~robofleet.avoidance.navigation.progress.ProgressChecker`):
    a filter cannot know the robot's goal, so the way is the motion asked for, and the
    distance left shrinks each step by the motion made along the asked direction. Over the
    last ``window`` steps a robot that asked for at least ``progress_fraction · v_max ·
    window · Δt`` of motion is *deadlocked* when it made less than that much progress along
    the directions it asked for, or when it asked to move and the filter returned ``u = 0``
    in a non-empty cell (it sits on the boundary).
    Recovery rotates the desired velocity clockwise by 90° (``R_z(−90°)``, the paper's
    goal rotation ``g_tmp = R_z(−90°)(g − p̂) + p̂`` written for a velocity) for
    ``recover_steps`` steps. The obstacle-vertex branch of appendix C needs the goal and
    is not applied. :class:`SafetyFilter` keeps no memory unless given ``deadlock``;
    :class:`RobotSafetyFilter` keeps its own robot's memory by default.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..core.arguments import count, flag, instance, sequence
from ..core.config import ScenarioSource, load_spec
from ..core.errors import ConfigError, short_repr
from ..core.spec_blocks import is_convex
from .cell import CellGeometry, Cells, cell_from_view
from .navigation.progress import DeadlockParams, ProgressChecker
from .obstacles import wall_planes
from .projection import project_onto_cells
from .separator import as_float_array, check_covariance, power_of_two_scale, scaled
from .cell_model import CellModel, cell_model, method_setup, obstacle_set, shifted
from .spec import Spec

_CLOCKWISE_90 = np.array([[0.0, 1.0], [-1.0, 0.0]])  # R_z(−90°), as in appendix C
DEFAULT_DEADLOCK = DeadlockParams()
"""The deadlock memory a :class:`RobotSafetyFilter` keeps by default (appendix C's parameters of the controller)."""


@dataclass(frozen=True)
class FilterResult:
    """What one call of a safety filter returns (one row per robot).

    velocity: ``(N, 2)`` the filtered velocities.
    desired: ``(N, 2)`` the desired velocities after the speed limit (and, while a robot
    recovers from a deadlock, rotated by −90°): what was projected.
    modified: ``(N,)`` the filter changed the desired velocity (beyond 1e-12 m/s).
    estimate_in_cell: ``(N,)`` the estimate lay in its own cell (premise of the bound).
    empty: ``(N,)`` the cell was empty (the velocity is zero).
    deadlocked: ``(N,)`` a deadlock was detected at this call (a recovery starts).
    recovering: ``(N,)`` the desired velocity was rotated by the deadlock recovery.
    cells: the cells the velocities were filtered with.
    """

    velocity: np.ndarray
    desired: np.ndarray
    modified: np.ndarray
    estimate_in_cell: np.ndarray
    empty: np.ndarray
    deadlocked: np.ndarray
    recovering: np.ndarray
    cells: Cells


# ---------------------------------------------------------------------------------------
# the filter itself (pure, vectorized)
# ---------------------------------------------------------------------------------------
def saturate(velocity: np.ndarray, v_max: np.ndarray) -> np.ndarray:
    """``u · min(1, v_max / ‖u‖)`` per row: the speed limit (any finite ``u``, e.g. 1e200 m/s,
    keeps its direction; :func:`limited_velocity` with Δt = 1)."""
    return limited_velocity(velocity, v_max, 1.0)


def limited_velocity(displacement: np.ndarray, v_max: np.ndarray, dt: float) -> np.ndarray:
    """The velocity ``Δ/Δt`` of each row's displacement ``Δ``, shortened to ``v_max`` along
    the same direction when faster; rows within the limit are returned as ``Δ/Δt`` exactly.

    Computed without overflow for any finite ``Δ``, ``v_max`` and ``Δt > 0``: the rows are
    scaled by powers of two (exact) so that ``‖Δ‖`` is compared with ``v_max Δt`` and the
    direction ``Δ/‖Δ‖`` is taken on numbers near 1."""
    exponent = power_of_two_scale(displacement, (1,))
    unit = scaled(displacement, exponent)
    length = np.hypot(unit[:, 0], unit[:, 1])  # ‖Δ‖ · 2^-e, in [½, √2) unless Δ = 0
    with np.errstate(over="ignore", under="ignore"):
        reach = np.ldexp(np.asarray(v_max, dtype=float) * dt, -exponent)  # v_max Δt · 2^-e (overflow: never too fast)
    too_fast = length > reach
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        within = displacement / dt  # used only where ‖Δ‖ ≤ v_max Δt: at most v_max
    direction = unit / np.where(too_fast, length, 1.0)[:, None]
    return np.where(too_fast[:, None], direction * np.asarray(v_max, dtype=float).reshape(-1, 1), within)


def safe_velocities(estimates: np.ndarray, desired: np.ndarray, cells: Cells, v_max: np.ndarray,
                    dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The B-UAVC filter (see the module docstring): ``(velocity, estimate_in_cell, empty)``.

    ``u = (Π_V(p̂ + sat(u_des) Δt) − p̂)/Δt``, shortened to ``v_max`` when ``p̂ ∉ V``; zero
    for an empty cell. O(N · V · M²) for M constraints of which V are violated.
    """
    wanted = saturate(desired, v_max)
    query = estimates + wanted * dt
    proj = project_onto_cells(query, cells)
    inside = cells.contains(estimates)
    target = np.where(proj.empty[:, None], estimates, proj.point)
    velocity = limited_velocity(target - estimates, v_max, dt)
    kept = np.all(proj.point == query, axis=1)  # already in the cell: exactly the desired velocity
    return np.where(kept[:, None], wanted, velocity), inside, proj.empty


# ---------------------------------------------------------------------------------------
# deadlock memory (appendix C, velocity form)
# ---------------------------------------------------------------------------------------
@dataclass
class DeadlockMemory:
    """Per-robot memory of the deadlock heuristic: the progress checker on the motion made
    along the asked directions, the ring of asked motion, and the recoveries."""

    params: DeadlockParams
    checker: ProgressChecker
    asked: np.ndarray
    left: np.ndarray
    recover_left: np.ndarray

    @classmethod
    def initial(cls, params: DeadlockParams, n: int) -> DeadlockMemory:
        window = max(params.window, 1)
        return cls(params, ProgressChecker(params, n, 1.0, 1.0), np.full((window, n), np.nan), np.zeros(n), np.zeros(n, np.int64))

    @property
    def deadlocks(self) -> np.ndarray:
        """Deadlock detections per robot so far."""
        return self.checker.deadlocks

    def steer(self, desired: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The desired velocities to project: rotated by −90° for robots in recovery."""
        recovering = self.recover_left > 0
        steered = desired.copy()
        steered[recovering] = desired[recovering] @ _CLOCKWISE_90.T
        return steered, recovering

    def update(self, asked: np.ndarray, velocity: np.ndarray, empty: np.ndarray, v_max: np.ndarray, dt: float) -> np.ndarray:
        """Record one step (``asked``: the projected desired velocities) and return the
        robots newly detected in deadlock, whose recovery starts now."""
        checker = self.checker
        checker.v_max, checker.dt = v_max, dt
        asked_len = np.linalg.norm(asked, axis=1) * dt
        along = np.einsum("ij,ij->i", velocity, asked) * dt / np.maximum(asked_len / dt, 1e-300)
        self.asked[checker.step % len(self.asked)] = asked_len
        self.left = self.left - along  # the distance left shrinks by the motion made along the asked direction
        normal = self.recover_left <= 0
        self.recover_left = np.maximum(self.recover_left - 1, 0)
        driving = normal & np.all(np.isfinite(self.asked), axis=0) & (np.nansum(self.asked, axis=0) >= checker.threshold)
        sitting = (asked_len > 1e-9) & (np.linalg.norm(velocity, axis=1) * dt < 1e-9) & ~empty
        stuck = checker.observe(self.left, driving | (sitting & normal), sitting)
        self.asked[:, stuck] = np.nan
        self.recover_left[stuck] = self.params.recover_steps
        return stuck


# ---------------------------------------------------------------------------------------
# input checking
# ---------------------------------------------------------------------------------------
MAX_LENGTH = 1e100
"""Largest coordinate, radius, speed limit and step ``v_max Δt`` (m, m/s) the filters accept:
sums and squares of such lengths stay finite in floating point."""
MAX_VARIANCE = 1e300
"""Largest covariance entry (m²) the filters accept (its chance buffer stays finite)."""


def positive(value: object, name: str, most: float = np.inf) -> float:
    """``value`` as a finite float in ``(0, most]``, or a :class:`ConfigError` naming ``name``."""
    array = as_float_array(value, name)
    if array.ndim != 0 or not 0 < float(array) <= most:
        limit = "> 0" if most == np.inf else f"in (0, {most:g}]"
        raise ConfigError(f"{name}: expected a number {limit}, received {short_repr(value)}")
    return float(array)


def per_robot_positive(value: object, name: str, n: int, most: float = np.inf) -> np.ndarray:
    """A number or ``(n,)`` numbers, each in ``(0, most]``, as an ``(n,)`` array."""
    array = as_float_array(value, name)
    if array.ndim > 1 or (array.ndim == 1 and len(array) != n):
        raise ConfigError(f"{name}: expected a number or {n} numbers (one per robot), received shape {array.shape}")
    if np.any(array <= 0) or np.any(array > most):
        limit = "> 0" if most == np.inf else f"in (0, {most:g}]"
        raise ConfigError(f"{name}: expected numbers {limit}, received {short_repr(array.tolist())}")
    return np.broadcast_to(array, (n,)).astype(float)


def step_length(v_max: np.ndarray, dt: float) -> None:
    """Refuse a step ``v_max Δt`` longer than :data:`MAX_LENGTH`."""
    if float(np.max(v_max)) * dt > MAX_LENGTH:
        raise ConfigError(f"v_max, dt: expected a step v_max·dt ≤ {MAX_LENGTH:g} m, received {float(np.max(v_max)):g} m/s × {dt:g} s")


def points(value: object, name: str, n: int | None = None, most: float = MAX_LENGTH) -> np.ndarray:
    """``(n, 2)`` finite numbers of magnitude ``≤ most`` (any ``n`` when ``n`` is None)."""
    array = as_float_array(value, name)
    if array.ndim != 2 or array.shape[1] != 2 or (n is not None and len(array) != n):
        expected = f"({n}, 2)" if n is not None else "(N, 2)"
        raise ConfigError(f"{name}: expected an array shaped {expected}, received shape {array.shape}")
    return within(array, name, most)


def point(value: object, name: str, most: float = MAX_LENGTH) -> np.ndarray:
    """One finite point ``(2,)`` of magnitude ``≤ most``, returned as a ``(1, 2)`` row."""
    array = as_float_array(value, name)
    if array.shape != (2,):
        raise ConfigError(f"{name}: expected an array shaped (2,), received shape {array.shape}")
    return within(array, name, most)[None]


def within(array: np.ndarray, name: str, most: float) -> np.ndarray:
    """``array`` if no entry exceeds ``most`` in magnitude."""
    if array.size and np.abs(array).max() > most:
        raise ConfigError(f"{name}: expected numbers of magnitude ≤ {most:g}, received {short_repr(array.tolist())}")
    return array


def covariances(value: object, name: str, n: int) -> np.ndarray:
    """``(2, 2)`` (shared) or ``(n, 2, 2)`` symmetric PSD matrices, as ``(n, 2, 2)``."""
    array = as_float_array(value, name)
    if array.shape not in ((2, 2), (n, 2, 2)):
        raise ConfigError(f"{name}: expected an array shaped (2, 2) or ({n}, 2, 2), received shape {array.shape}")
    check_covariance(within(array, name, MAX_VARIANCE), name)
    return np.broadcast_to(array, (n, 2, 2))


def obstacle_offsets(value: object, count: int) -> np.ndarray:
    """The obstacles' estimated displacements ``(O, 2)`` (zeros when ``None``)."""
    if value is None:
        return np.zeros((count, 2))
    return points(value, "obstacle_offsets", count)


def deadlock_params(value: object) -> DeadlockParams | None:
    """``None`` or a :class:`~.controller.DeadlockParams` with a window and recovery of at
    least one step and a progress fraction in (0, 1)."""
    if value is None:
        return None
    params = instance(value, DeadlockParams, "deadlock", "DeadlockParams or None")
    flag(params.enabled, "deadlock.enabled")
    count(params.window, "deadlock.window", minimum=1)
    count(params.recover_steps, "deadlock.recover_steps", minimum=1)
    fraction = as_float_array(params.progress_fraction, "deadlock.progress_fraction")
    if fraction.ndim != 0 or not 0 < float(fraction) < 1:
        raise ConfigError(f"deadlock.progress_fraction: expected a number in (0, 1), received {short_repr(params.progress_fraction)}")
    return params


def cell_geometry(bounds: object, obstacles: object, obstacle_cov: object, delta: float, radius: float) -> CellGeometry:
    """Walls and obstacles (with their ε-shadows under ``Σ_o``, appendix A) of the cells of
    robots whose largest radius is ``radius``."""
    polygons = [convex_polygon(o, f"obstacles[{k}]") for k, o in enumerate(sequence(obstacles, "obstacles", "convex polygons (V, 2)"))]
    cov = covariances(np.zeros((2, 2)) if obstacle_cov is None else obstacle_cov, "obstacle_cov", 1)[0]
    obstacle_set_ = obstacle_set(polygons, cov, method_setup("buavc", delta, 0.0))
    wall_a, wall_b = wall_planes(bounds_polygon(bounds, radius)) if bounds is not None else (np.zeros((0, 2)), np.zeros(0))
    return CellGeometry(obstacle_set_, wall_a, wall_b)


def convex_polygon(value: object, name: str) -> np.ndarray:
    """``(V, 2)`` vertices of a convex polygon with positive area: at least 3 vertices, no
    two consecutive ones equal, not all on one line (area ≤ 1e-12 × its extent² counts as
    a line), coordinates within :data:`MAX_LENGTH`."""
    polygon = points(value, name)
    if len(polygon) < 3 or np.any(np.all(np.roll(polygon, -1, axis=0) == polygon, axis=1)) or not _has_area(polygon) or not is_convex(polygon):
        raise ConfigError(f"{name}: expected a convex polygon of at least 3 distinct vertices with positive area, "
                          f"received {short_repr(polygon.tolist())}")
    return polygon


def _has_area(polygon: np.ndarray) -> bool:
    """Twice the (shoelace) area above 1e-12 × the polygon's extent²: not all on one line."""
    extent = float(np.ptp(polygon, axis=0).max())
    area2 = abs(float(np.sum(polygon[:, 0] * np.roll(polygon[:, 1], -1) - np.roll(polygon[:, 0], -1) * polygon[:, 1])))
    return area2 > 1e-12 * extent**2


def bounds_polygon(bounds: object, radius: float) -> np.ndarray:
    """``(xmin, ymin, xmax, ymax)`` or a convex polygon ``(V, 2)`` as polygon vertices, with
    room for a robot of ``radius`` (a disc of that radius fits inside)."""
    array = as_float_array(bounds, "bounds")
    if array.shape == (4,):
        x0, y0, x1, y1 = within(array, "bounds", MAX_LENGTH)
        if not (x0 < x1 and y0 < y1):
            raise ConfigError(f"bounds: expected (xmin, ymin, xmax, ymax) with xmin < xmax and ymin < ymax, received {short_repr(array.tolist())}")
        polygon = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    elif array.ndim == 2 and array.shape[1] == 2:
        polygon = convex_polygon(array, "bounds")
    else:
        raise ConfigError(f"bounds: expected (xmin, ymin, xmax, ymax) or a convex polygon (V, 2), received shape {array.shape}")
    if not holds_disc(polygon, radius):
        raise ConfigError(f"bounds: expected a workspace with room for a robot of radius {radius:g}, received {short_repr(polygon.tolist())}")
    return polygon


def holds_disc(polygon: np.ndarray, radius: float) -> bool:
    """Whether a disc of ``radius`` fits in the convex ``polygon``: its walls moved in by the
    radius still leave a point (the projection onto them is not empty)."""
    a, b = wall_planes(polygon)
    m = len(b)
    shrunk = Cells(a[None], (b - radius)[None], np.ones((1, m), bool), np.full((1, m), 2, np.int8), np.arange(m)[None])
    return not bool(project_onto_cells(polygon.mean(axis=0)[None], shrunk).empty[0])


def single_integrator_spec(spec: Spec) -> Spec:
    """``spec`` if every team is a 2-D single integrator, else a :class:`ConfigError`."""
    kinds = sorted({t.model.kind for t in spec.team_specs()})
    if spec.dim != 2 or kinds != ["single_integrator"]:
        raise ConfigError(f"scenario: expected a 2-D scenario of single-integrator robots (the filter's model), "
                          f"received dimension {spec.dim} with models {kinds}")
    return spec


# ---------------------------------------------------------------------------------------
# the two faces: batched over a fleet, and one robot's own
# ---------------------------------------------------------------------------------------
@dataclass
class SafetyFilter:
    """B-UAVC safety filter for a fleet of ``n`` single-integrator robots, batched and
    vectorized over the robots (see the module docstring for the guarantee).

    Build it with :meth:`create` (geometry given directly) or :meth:`from_spec` (an
    avoidance scenario), then call :meth:`filter` every control step with the current
    estimates, covariances and desired velocities of all ``n`` robots.

    Attributes
    ----------
    model: the cell ingredients (radii, buffer quantile, walls, obstacles, ``R_loc``).
    v_max: ``(n,)`` speed limits.
    dt: control step Δt.
    memory: the deadlock memory (``None``: stateless, the same input gives the same output).
    """

    model: CellModel
    v_max: np.ndarray
    dt: float
    memory: DeadlockMemory | None = field(default=None)

    @property
    def n(self) -> int:
        return len(self.v_max)

    @classmethod
    def create(cls, n: int, *, radius: float | Sequence[float], dt: float, v_max: float | Sequence[float], delta: float = 0.1,
               bounds: object = None, obstacles: Sequence = (), obstacle_cov: object = None, local_box: float = 2.0,
               deadlock: DeadlockParams | None = None) -> SafetyFilter:
        """A filter for ``n`` robots.

        Lengths (coordinates, radii, v_max, the step ``v_max Δt``) are at most
        :data:`MAX_LENGTH`, covariance entries at most :data:`MAX_VARIANCE`; anything else
        is a :class:`~robofleet.core.errors.ConfigError` naming the argument.

        Parameters
        ----------
        radius, v_max: the safety radius r_i and the speed limit, one value or one per robot
            (radii may differ: each pair keeps ``r_i + r_j``, :mod:`.cell`).
        dt: the control step Δt [s].
        delta: the collision threshold δ ∈ (0, 1) of the chance constraint.
        bounds: the workspace, ``(xmin, ymin, xmax, ymax)`` or a convex polygon with room
            for the largest robot; ``None``: no walls.
        obstacles: convex polygons ``(V_k, 2)`` at their nominal positions.
        obstacle_cov: ``Σ_o`` ``(2, 2)`` of the obstacles' positions (``None``: known exactly).
        local_box: R_loc, half-width of the box around each estimate that is considered.
        deadlock: parameters of the deadlock memory (appendix C); ``None`` keeps none.
        """
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ConfigError(f"n: expected a positive integer number of robots, received {short_repr(n)}")
        radii, v_max, dt = per_robot_positive(radius, "radius", n, MAX_LENGTH), per_robot_positive(v_max, "v_max", n, MAX_LENGTH), positive(dt, "dt")
        step_length(v_max, dt)
        quantile = method_setup("buavc", delta, 0.0).quantile
        geometry = cell_geometry(bounds, obstacles, obstacle_cov, delta, float(radii.max()))
        model = CellModel(np.zeros((n, 2, 2)), radii, quantile, geometry, positive(local_box, "local_box"))
        return cls._with_memory(model, v_max, dt, deadlock_params(deadlock))

    @classmethod
    def from_spec(cls, spec: ScenarioSource, deadlock: DeadlockParams | None = None) -> SafetyFilter:
        """The filter of an avoidance scenario's robots: its r_s, v_max per team, δ,
        Δt, R_loc, walls and obstacles with their ε-shadows (always as B-UAVC, whatever the
        scenario's ``method``). The scenario's Σ are the default covariances
        (:meth:`covariances`), but every call passes its own. ``spec``: a shipped name, a
        YAML file, a mapping or a validated spec (:func:`~robofleet.core.config.load_spec`)."""
        spec = single_integrator_spec(load_spec(spec, Spec, argument="spec"))
        model = cell_model(spec, method_setup("buavc", spec.delta, 0.0))
        v_max = np.concatenate([np.full(t.n, t.v_max) for t in spec.team_specs()])
        return cls._with_memory(model, v_max, float(spec.dt), deadlock_params(deadlock))

    @classmethod
    def _with_memory(cls, model: CellModel, v_max: np.ndarray, dt: float, deadlock: DeadlockParams | None) -> SafetyFilter:
        memory = DeadlockMemory.initial(deadlock, len(v_max)) if deadlock is not None and deadlock.enabled else None
        return cls(model, v_max, dt, memory)

    @property
    def covariances(self) -> np.ndarray:
        """The covariances the filter was built with (the scenario's Σ; zeros from :meth:`create`)."""
        return self.model.covs

    @property
    def obstacle_count(self) -> int:
        return self.model.geometry.obstacles.count

    def reset(self) -> None:
        """Forget the deadlock memory (a new episode)."""
        if self.memory is not None:
            self.memory = DeadlockMemory.initial(self.memory.params, self.n)

    def cells(self, estimates: np.ndarray, covs: np.ndarray, offsets: np.ndarray | None = None) -> Cells:
        """Every robot's B-UAVC from the estimates ``(n, 2)`` and covariances ``(n, 2, 2)``."""
        model = replace(self.model, covs=covs)
        return model.cells(estimates, obstacle_offsets(offsets, self.obstacle_count))

    def filter(self, estimates: object, covs: object, desired: object, obstacle_offsets: object = None) -> FilterResult:
        """Filter the desired velocities of all robots for one step.

        Parameters
        ----------
        estimates: ``(n, 2)`` position estimates p̂.
        covs: ``(2, 2)`` shared or ``(n, 2, 2)`` covariances Σ of the estimates.
        desired: ``(n, 2)`` desired velocities (any source).
        obstacle_offsets: ``(O, 2)`` estimated displacements of the obstacles from their
            nominal positions (``None``: at their nominal positions).
        """
        p = distinct(points(estimates, "estimates", self.n), "estimates")
        cov = covariances(covs, "covs", self.n)
        wanted = points(desired, "desired", self.n, np.inf)
        cells = self.cells(p, cov, obstacle_offsets)
        return filtered(p, wanted, cells, self.v_max, self.dt, self.memory)


def distinct(points_: np.ndarray, name: str) -> np.ndarray:
    """``points_`` if no two rows are equal (no separator exists between equal estimates)."""
    _, first, counts = np.unique(points_, axis=0, return_index=True, return_counts=True)
    if np.any(counts > 1):
        raise ConfigError(f"{name}: expected distinct positions (no separator exists between equal estimates), "
                          f"received equal rows at {points_[first[counts > 1][0]].tolist()}")
    return points_


def filtered(p: np.ndarray, desired: np.ndarray, cells: Cells, v_max: np.ndarray, dt: float, memory: DeadlockMemory | None) -> FilterResult:
    """Limit the speed, steer (deadlock recovery), filter and remember one step."""
    if not np.all(np.isfinite(cells.b)):
        raise ConfigError(f"estimates: expected cells of finite constraints, received non-finite ones for robot(s) "
                          f"{np.flatnonzero(~np.all(np.isfinite(cells.b), axis=1))[:6].tolist()}")
    wanted = saturate(desired, v_max)
    steered, recovering = (wanted, np.zeros(len(p), bool)) if memory is None else memory.steer(wanted)
    velocity, inside, empty = safe_velocities(p, steered, cells, v_max, dt)
    stuck = np.zeros(len(p), bool) if memory is None else memory.update(steered, velocity, empty, v_max, dt)
    change = np.minimum(np.abs(velocity - desired), 1.0)  # clipped: the same test, no overflow for huge desired velocities
    modified = np.hypot(change[:, 0], change[:, 1]) > 1e-12
    return FilterResult(velocity, steered, modified, inside, empty, stuck, recovering, cells)


@dataclass
class RobotSafetyFilter:
    """One robot's B-UAVC safety filter, fed only what that robot sees: its own estimate
    and covariance, its neighbours' estimates and covariances (those outside ``R_loc`` are
    ignored, as in the batch filter), and the obstacles. It keeps its own deadlock memory.

    The cell is built by :func:`~.cell.cell_from_view`, the reference the batch builder is
    tested against, so a robot filtering alone gets the velocity :class:`SafetyFilter`
    computes for it from the same estimates (the tests check it). The typical use is one
    instance per robot process, e.g. inside a ROS 2 node (see the docs' embedding page).
    """

    radius: float
    v_max: float
    dt: float
    quantile: float
    geometry: CellGeometry
    local_box: float
    memory: DeadlockMemory | None

    @classmethod
    def create(cls, *, radius: float, dt: float, v_max: float, delta: float = 0.1, bounds: object = None, obstacles: Sequence = (),
               obstacle_cov: object = None, local_box: float = 2.0,
               deadlock: DeadlockParams | None = DEFAULT_DEADLOCK) -> RobotSafetyFilter:
        """A robot's filter; parameters as in :meth:`SafetyFilter.create` (one robot; the
        deadlock memory is on by default, ``deadlock=None`` turns it off)."""
        radius, v_max, dt = positive(radius, "radius", MAX_LENGTH), positive(v_max, "v_max", MAX_LENGTH), positive(dt, "dt")
        step_length(np.array([v_max]), dt)
        quantile = method_setup("buavc", delta, 0.0).quantile
        deadlock = deadlock_params(deadlock)
        memory = DeadlockMemory.initial(deadlock, 1) if deadlock is not None and deadlock.enabled else None
        return cls(radius, v_max, dt, quantile, cell_geometry(bounds, obstacles, obstacle_cov, delta, radius), positive(local_box, "local_box"), memory)

    @classmethod
    def from_spec(cls, spec: ScenarioSource, robot: int = 0, deadlock: DeadlockParams | None = DEFAULT_DEADLOCK) -> RobotSafetyFilter:
        """Robot ``robot``'s filter in an avoidance scenario (its team's v_max; ``spec`` as
        in :meth:`SafetyFilter.from_spec`)."""
        fleet = SafetyFilter.from_spec(spec)
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 0 <= robot < fleet.n:
            raise ConfigError(f"robot: expected an index in 0..{fleet.n - 1}, received {short_repr(robot)}")
        m = fleet.model
        deadlock = deadlock_params(deadlock)
        memory = DeadlockMemory.initial(deadlock, 1) if deadlock is not None and deadlock.enabled else None
        return cls(float(m.radius[robot]), float(fleet.v_max[robot]), fleet.dt, m.quantile, m.geometry, m.local_box, memory)

    def reset(self) -> None:
        """Forget the deadlock memory."""
        if self.memory is not None:
            self.memory = DeadlockMemory.initial(self.memory.params, 1)

    def cell(self, estimate: np.ndarray, cov: np.ndarray, neighbours: np.ndarray, neighbour_covs: np.ndarray,
             offsets: object = None, neighbour_radii: np.ndarray | None = None) -> Cells:
        """This robot's B-UAVC from its local view, as a one-robot :class:`~.cell.Cells`
        (``neighbour_radii``: one per neighbour, ``None``: the robot's own radius)."""
        geometry = replace(self.geometry, obstacles=shifted(self.geometry.obstacles, obstacle_offsets(offsets, self.geometry.obstacles.count)))
        A, b, kind = cell_from_view(estimate, cov, self.radius, neighbours, neighbour_covs, self.quantile, geometry, self.local_box,
                                    neighbour_radii=neighbour_radii)
        m = max(len(b), 1)
        cells = Cells(np.zeros((1, m, 2)), np.ones((1, m)), np.zeros((1, m), bool), np.full((1, m), -1, np.int8), np.full((1, m), -1, np.intp))
        cells.A[0, : len(b)], cells.b[0, : len(b)], cells.valid[0, : len(b)], cells.kind[0, : len(b)] = A, b, True, kind
        return cells

    def filter(self, estimate: object, covariance: object, desired: object, neighbour_estimates: object = (),
               neighbour_covariances: object = None, obstacle_offsets: object = None,
               neighbour_radii: object = None) -> FilterResult:
        """Filter this robot's desired velocity ``(2,)`` for one step.

        Parameters
        ----------
        estimate, covariance: the robot's own p̂ ``(2,)`` and Σ ``(2, 2)``.
        desired: the desired velocity ``(2,)`` (any finite one; faster than v_max keeps its
            direction).
        neighbour_estimates: ``(K, 2)`` the estimates its neighbours report (any K ≥ 0).
        neighbour_covariances: ``(2, 2)`` shared or ``(K, 2, 2)``; ``None``: the robot's own Σ.
        obstacle_offsets: ``(O, 2)`` estimated displacements of the obstacles.
        neighbour_radii: the neighbours' radii, one for all or ``(K,)``; ``None``: the
            robot's own radius. The cell keeps ``(r_i + r_j)/2`` from each pair's plane,
            as the batch filter does, so pairs with different radii stay ``r_i + r_j``
            apart (:mod:`.cell`); every robot must be given the others' true radii.

        Returns
        -------
        FilterResult
            One row: ``result.velocity[0]`` is the velocity to apply.
        """
        p = point(estimate, "estimate")
        cov = covariances(covariance, "covariance", 1)
        nb = np.zeros((0, 2)) if np.size(neighbour_estimates) == 0 else points(neighbour_estimates, "neighbour_estimates")
        distinct(np.concatenate([p, nb]), "neighbour_estimates")
        ncov = covariances(cov[0] if neighbour_covariances is None else neighbour_covariances, "neighbour_covariances", len(nb))
        radii = None if neighbour_radii is None else per_robot_positive(neighbour_radii, "neighbour_radii", len(nb), MAX_LENGTH)
        cells = self.cell(p[0], cov[0], nb, ncov, obstacle_offsets, radii)
        return filtered(p, point(desired, "desired", np.inf), cells, np.array([self.v_max]), self.dt, self.memory)
