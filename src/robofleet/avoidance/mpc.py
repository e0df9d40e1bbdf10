"""B-UAVC receding-horizon control (MPC) for any robot model (Zhu et al. 2022, Sec. 5.4 and
appendix C; ``docs/theory/buavc.md`` "Controllers").

Each control step robot ``i`` solves ::

    min_{x, u}  ‖g − p_N‖² / max(‖g − p_0‖², 1)  +  w_u/N · Σ_k ‖u_k‖²
    s.t.        x_0 = x̂,   x_{k+1} = f(x_k, u_k)            (the model's discrete step)
                A p_k ≤ b,   k = 1 … N                      (every predicted position in the
                                                             current B-UAVC)
                u_lo ≤ u_k ≤ u_hi (and the model's norm limits)
                quadrotor: |v_xy,k| ≤ v_max (inscribed 8-gon),  v_N = 0, φ_N = θ_N = 0

and applies ``u_0``. Linear models (single and double integrator) are solved as a QP
(qpOASES through casadi's ``qpsol``, built **once** per (model, horizon, max constraints):
the cell enters as parameters ``A (M × d)``, ``b (M)``, unused rows padded with the
always-true ``0·p ≤ 1``). Nonlinear ones (unicycle, quadrotor) are solved by default
(``solver: rti``) with the braking-safe real-time-iteration SQP of :mod:`.rti` (condensed
Gauss–Newton QPs around the previous plan shifted by one step, solved by DAQP, every cell
row the plan can reach), or (``solver: ipopt``) as the full NLP with IPOPT (``nlpsol``),
warm-started from the shifted plan.

A plan is *in the cell* when its inputs, rolled out with the model's discrete step (the
simulator's equations), keep every predicted position in the cell; only such a step counts
as solved (``mpc_status`` 0). Without one — the estimate lies outside its cell (its first
predicted position is fixed by the current velocity), or no plan can stop inside a cell
that shrank — the step is a fallback (``mpc_status`` 1): the IPOPT path first tries the
previous plan shifted by one step; nonlinear models then apply the SQP's least-violating
plan, which re-enters the cell as early as the dynamics allow; only if that fails (and for
the linear models) the robot applies its model's safe fallback (zero input; for the double
integrator the brake of :mod:`.braking`; for the quadrotor a tilt against its horizontal
velocity, zero climb: :func:`~robofleet.dynamics.quadrotor.braking_control`).

Our additions to the paper's formulation (the paper gives no details of its
quadrotor MPC beyond "every predicted position in the current B-UAVC"):

* the **terminal rest set** ``v_N = 0, φ_N = θ_N = 0`` (``terminal_rest``, within
  ``rest_tolerance``) for the quadrotor: every plan contains a way to stop inside the cell
  it was planned in, and its shifted continuation by the zero input stays there (the
  terminal-set argument of Mayne et al. 2000). Without it plans ended at full speed on the
  cell boundary, and the robot had no plan once the cell shrank;
* the **speed limit** ``|v_xy| ≤ v_max`` of the quadrotor's team (``speed_limit``; before,
  the quadrotor MPC ignored ``v_max`` and flew at up to 4.5 m/s, where the 1 s horizon and
  the 2 m local box no longer leave room to stop);
* the **least-violating plan** instead of pure braking when no in-cell plan exists (an
  exact ℓ1 penalty on the cell constraints, :mod:`.rti`);
* the **noise band** (``'rti'`` path): predicted positions of stages ``2 … N`` prefer to
  keep ``noise_band · σ`` from the cell's faces (``σ`` = the robot's position noise, largest
  standard deviation; shrunk linearly to 0 within one plan's reach of the goal, ``N·Δt·v_max``,
  so that a goal near a face stays reachable; a soft tightening, traded against the goal). The
  cell is rebuilt every step from fresh estimates, so a robot that parks on a face finds
  its next estimate outside its next cell about half of the time; with the band it parks
  a little inside. Stage 1 — where B-UAVC's chance constraint acts — keeps the exact cell.
* ``'rti'`` uses every valid cell row (the QP drops the rows no admissible plan reaches),
  the casadi solvers the ``max_constraints`` tightest.
* robots that have arrived keep solving toward their goal (before, they braked and
  ignored their cell, and a hovering quadrotor drifted into a passing ground robot); their
  steps are ``mpc_status`` 2 and not counted in the fallback share.

Deadlock (appendix C, :class:`~robofleet.avoidance.navigation.recovery.GoalRotation`): when a robot that has not arrived moves
less than ``Δp_min`` over the last ``n_dead`` steps, its goal is rotated clockwise by
90° about the robot, ``g_tmp = R_z(−90°)(g − p̂) + p̂``, for ``recover_steps`` steps.

The input weight ``w_u`` (default 1e-3) is our addition: the terminal cost alone leaves
the input sequence undetermined; the small weight selects the least-effort plan.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field

from ..core.config import SpecModel
from ..core.errors import ConfigError
from ..core.output import quiet_stdout
from ..dynamics import double_integrator as di
from ..dynamics import quadrotor as quad
from ..dynamics import unicycle as uni
from .braking import braking_control
from .controller_params import MPCConfig
from .navigation.recovery import GoalRotation
from .rti import CondensedSQP, SQPResult, StateLimit, import_daqp

ModelName = Literal["single_integrator", "double_integrator", "unicycle", "quadrotor"]
MODEL_NAMES = ("single_integrator", "double_integrator", "unicycle", "quadrotor")
_POLYGON_SIDES = 8
_CELL_TOL = 1e-9
CELL_MARGIN = 1e-3  # the solver sees the cell shrunk by 1 mm, so that a plan within the
#                     solver's constraint tolerance lies in the true cell (checked before use)
QP_SOLVER = "qpoases"
QP_OPTIONS = {
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False},
    "qpoases": {"printLevel": "none", "error_on_fail": False},
    "osqp": {"osqp": {"verbose": False, "eps_abs": 1e-7, "eps_rel": 1e-7}, "error_on_fail": False},
}


class SingleIntegratorParams(SpecModel):
    """Speed limit of a single integrator in the MPC."""

    v_max: float = Field(gt=0)


@dataclass(frozen=True)
class ModelAdapter:
    """What the MPC needs to know about a robot model.

    ``polytope_limits`` are ``(vector part, index slice, limit)``: ``‖·‖ ≤ limit`` kept with an
    inscribed regular ``8``-gon (linear, so linear models stay QPs).
    """

    name: str
    nx: int
    nu: int
    dim: int
    linear: bool
    step: Callable  # symbolic (x, u) -> x⁺
    u_lo: np.ndarray
    u_hi: np.ndarray
    norm_limits: tuple  # ((kind "u"|"x", slice, limit), ...)
    fallback: Callable  # (states (n, nx)) -> controls (n, nu)
    rest: slice | None = None  # state components that vanish at rest under the zero input


@dataclass(frozen=True)
class PlanResult:
    """One robot-step's outcome: the input to apply (``None``: the model's safe fallback),
    the inputs ``(N, nu)`` and predicted positions ``(N+1, d)`` of the applied plan, and
    whether every predicted position lies in the cell (else the plan is the least-violating
    one, or there is none)."""

    control: np.ndarray | None
    positions: np.ndarray | None
    in_cell: bool
    inputs: np.ndarray | None = None


def model_adapter(name: str, params: SingleIntegratorParams | di.DoubleIntegratorParams | uni.UnicycleParams | quad.QuadrotorParams,
                  dim: int, dt: float, speed_limit: float | None = None) -> ModelAdapter:
    """The :class:`ModelAdapter` of model ``name`` (one of :data:`MODEL_NAMES`); ``speed_limit``
    bounds the quadrotor's horizontal speed (the other models carry theirs in ``params``)."""
    inf = np.inf
    if name == "single_integrator":
        return ModelAdapter(name, dim, dim, dim, True, lambda x, u: x + u * dt, np.full(dim, -inf), np.full(dim, inf),
                            (("u", slice(0, dim), params.v_max),), lambda s: np.zeros((len(s), dim)))
    if name == "double_integrator":
        return ModelAdapter(name, 2 * dim, dim, dim, True, lambda x, u: di.symbolic_step(x, u, dt, params, dim), np.full(dim, -inf), np.full(dim, inf),
                            (("u", slice(0, dim), params.a_max), ("x", slice(dim, 2 * dim), params.v_max)),
                            lambda s: braking_control(s[:, dim:], params.a_max, dt))
    if name == "unicycle":
        hi = np.array([params.v_max, params.omega_max])
        return ModelAdapter(name, 3, 2, 2, False, lambda x, u: uni.symbolic_step(x, u, dt, params), -hi, hi, (), lambda s: np.zeros((len(s), 2)))
    if name == "quadrotor":
        lo, hi = params.control_bounds()
        limits = () if speed_limit is None else (("x", slice(3, 5), speed_limit),)
        return ModelAdapter(name, 9, 4, 3, False, lambda x, u: quad.symbolic_step(x, u, dt, params), lo, hi, limits,
                            lambda s: quad.braking_control(s, params), rest=slice(3, 8))
    raise ConfigError(f"model: expected one of {list(MODEL_NAMES)}, received {name!r}")


def _polygon_rows(limit: float, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_polygon` as normals and one offset per row."""
    normals, offset = _polygon(limit, dim)
    return normals, np.full(len(normals), offset)


def _polygon(limit: float, dim: int) -> tuple[np.ndarray, float]:
    """Inscribed polytope of the ball ``‖w‖ ≤ limit``: normals and offset (2D: 8-gon; 3D: 8-gon in xy + |z| bound)."""
    ang = 2 * np.pi * np.arange(_POLYGON_SIDES) / _POLYGON_SIDES
    planar = np.stack([np.cos(ang), np.sin(ang)], -1)
    if dim == 2:
        return planar, limit * np.cos(np.pi / _POLYGON_SIDES)
    rows = np.zeros((_POLYGON_SIDES + 2, dim))
    rows[:_POLYGON_SIDES, :2] = planar * np.sqrt(2.0)  # |w_xy| ≤ ℓ/√2 ∧ |w_z| ≤ ℓ/√2 ⊂ ball
    rows[_POLYGON_SIDES:, 2] = [np.sqrt(2.0), -np.sqrt(2.0)]
    return rows, limit * np.cos(np.pi / _POLYGON_SIDES)


BUILT_PROBLEMS_PER_THREAD = 8
"""How many built problems (:func:`built_problem`) a thread keeps, the most recently used."""

_built_problems = threading.local()

CASADI_BUILDING = threading.Lock()
"""Held while casadi builds symbolic expressions and functions: its symbolic graph is not
safe to build from two threads at once (a process aborts), so controllers built in
threads side by side build one at a time."""


@dataclass(frozen=True)
class BuiltProblem:
    """The symbolic MPC of one model and configuration, and what is derived from it alone:
    sizes, bounds (read-only), the exact rollout and step, and the ``'rti'`` path's
    :class:`~.rti.CondensedSQP` (none of them keeps state between calls)."""

    problem: dict
    nz: int
    ng: int
    lbg: np.ndarray
    ubg: np.ndarray
    lbz: np.ndarray
    ubz: np.ndarray
    rollout: Callable
    step: Callable
    sqp: CondensedSQP | None


def built_problem(model: ModelAdapter, config: MPCConfig, key: tuple) -> BuiltProblem:
    """:func:`build_problem` of ``model`` (whose arguments are ``key``) and ``config``, kept
    per thread for the :data:`BUILT_PROBLEMS_PER_THREAD` most recent keys: the runs of a
    sweep build it once. A built problem is a pure function of its key, so a kept one is
    exactly the one a fresh build would give."""
    kept = getattr(_built_problems, "kept", None)
    if kept is None:
        kept = _built_problems.kept = {}
    full_key = (key, config)
    built = kept.pop(full_key, None)
    if built is None:
        with CASADI_BUILDING:
            built = build_problem(model, config)
        while len(kept) >= BUILT_PROBLEMS_PER_THREAD:
            kept.pop(next(iter(kept)))
    kept[full_key] = built  # the most recently used last
    return built


def build_problem(model: ModelAdapter, config: MPCConfig) -> BuiltProblem:
    """The MPC of the module docstring for ``model``: decision ``z = (vec X, vec U)``, the
    parameters ``P = (x_0, goal, A, b)`` of one robot's step, cost, dynamics equalities,
    the cell rows at stages 1…N, the norm limits and the terminal rest set."""
    import casadi as ca

    m, N, M = model, config.horizon, config.max_constraints
    X = ca.SX.sym("X", m.nx, N + 1)
    U = ca.SX.sym("U", m.nu, N)
    P = ca.SX.sym("P", m.nx + m.dim + M * m.dim + M)
    x0, goal = P[: m.nx], P[m.nx : m.nx + m.dim]
    A = ca.reshape(P[m.nx + m.dim : m.nx + m.dim + M * m.dim], M, m.dim)
    b = P[m.nx + m.dim + M * m.dim :]
    pos = lambda x: x[: m.dim]
    start = pos(x0)
    scale = ca.fmax(ca.sumsqr(goal - start), 1.0)
    cost = ca.sumsqr(goal - pos(X[:, N])) / scale + config.input_weight / N * ca.sumsqr(U)
    eq = [X[:, 0] - x0] + [X[:, k + 1] - m.step(X[:, k], U[:, k]) for k in range(N)]
    ineq = [ca.mtimes(A, pos(X[:, k])) - b for k in range(1, N + 1)]
    for kind, sl, limit in m.norm_limits:
        normals, offset = _polygon(limit, sl.stop - sl.start)
        for k in range(N):
            vec = U[sl, k] if kind == "u" else X[sl, k + 1]
            ineq.append(ca.mtimes(ca.DM(normals), vec) - offset)
    rest = m.rest if config.terminal_rest else None
    if rest is not None:  # the terminal rest set (see the module docstring)
        ineq += [X[rest, N] - config.rest_tolerance, -X[rest, N] - config.rest_tolerance]
    g = ca.vertcat(*eq, *ineq)
    z = ca.vertcat(ca.vec(X), ca.vec(U))
    n_eq, ng = sum(e.numel() for e in eq), g.numel()
    xs, us = ca.SX.sym("xs", m.nx), ca.SX.sym("us", m.nu, N)
    states = [xs]
    for k in range(N):
        states.append(m.step(states[-1], us[:, k]))
    return BuiltProblem(
        {"x": z, "p": P, "f": cost, "g": g}, z.numel(), ng,
        read_only(np.concatenate([np.zeros(n_eq), np.full(ng - n_eq, -np.inf)])), read_only(np.zeros(ng)),
        read_only(np.concatenate([np.full(m.nx * (N + 1), -np.inf), np.tile(m.u_lo, N)])),
        read_only(np.concatenate([np.full(m.nx * (N + 1), np.inf), np.tile(m.u_hi, N)])),
        ca.Function("rollout", [xs, us], [ca.horzcat(*states)]), ca.Function("step", [xs, us[:, 0]], [m.step(xs, us[:, 0])]),
        None if m.linear else condensed_sqp(m, config, rest))


def condensed_sqp(m: ModelAdapter, config: MPCConfig, rest: slice | None) -> CondensedSQP:
    """The :class:`~.rti.CondensedSQP` of model ``m`` with its speed limit and rest set (the
    ``'rti'`` solver, and the recovery of ``'ipopt'``)."""
    limits = tuple(StateLimit(sl, *_polygon_rows(limit, sl.stop - sl.start)) for kind, sl, limit in m.norm_limits if kind == "x")
    return CondensedSQP(m.step, nx=m.nx, nu=m.nu, dim=m.dim, horizon=config.horizon, u_lo=m.u_lo, u_hi=m.u_hi,
                        input_weight=config.input_weight, iterations=config.sqp_iterations, limits=limits,
                        rest=rest, rest_tolerance=config.rest_tolerance)


def read_only(array: np.ndarray) -> np.ndarray:
    """``array``, no longer writable (it is shared by the controllers of a built problem)."""
    array.flags.writeable = False
    return array


class BuavcMPC:
    """One robot model's B-UAVC MPC, built once and solved for each robot every step.

    Parameters
    ----------
    model : one of :data:`MODEL_NAMES`
    params : the model's parameter object (``SingleIntegratorParams``, ``DoubleIntegratorParams``, ...)
    dim : workspace dimension of the positions (the unicycle is 2, the quadrotor 3)
    dt : control period
    config : :class:`MPCConfig`
    n_robots : how many robots share this controller (each keeps its own warm start)
    speed_limit : the quadrotor's horizontal speed limit (the team's ``v_max``; ``None``: none)
    """

    def __init__(self, model: str, params, *, dim: int, dt: float, config: MPCConfig, n_robots: int,
                 speed_limit: float | None = None, position_sigma: float = 0.0):
        if model not in MODEL_NAMES:
            raise ConfigError(f"model: expected one of {list(MODEL_NAMES)}, received {model!r}")
        if config.horizon <= 0:
            raise ConfigError(f"horizon: expected an integer > 0, received {config.horizon!r}")
        self.model = model_adapter(model, params, dim, dt, speed_limit)
        self._model_key = (model, params, dim, dt, speed_limit)
        self.band = config.noise_band * position_sigma
        self.reach = config.horizon * dt * (1.0 if speed_limit is None else speed_limit)  # how far one plan can go
        self.config = config
        self.dt = dt
        self.n_robots = n_robots
        self._build()
        N, m = config.horizon, self.model
        self._warm = np.full((n_robots, self._problem.nz), np.nan)
        self._lam_g = np.zeros((n_robots, self._problem.ng))
        self.rotation = GoalRotation(n_robots, config.deadlock_steps, config.deadlock_progress, config.recover_steps)
        self.infeasible = np.zeros(n_robots, np.int64)
        del N, m

    @property
    def deadlocks(self) -> np.ndarray:
        """Deadlock detections per robot so far."""
        return self.rotation.deadlocks

    # ------------------------------------------------------------------ problem build
    def _build(self) -> None:
        """The problem of this model and configuration (:func:`built_problem`, shared by
        every controller built alike in this thread) and this controller's own QP/NLP
        solver: qpOASES hot-starts from its previous call, so a solver is never shared."""
        built = built_problem(self.model, self.config, self._model_key)
        if built.sqp is not None:
            import_daqp()  # a kept problem checks for its QP solver as a fresh build does
        self._problem = built
        self._first_solve = True
        with CASADI_BUILDING:
            self._solver = self._own_solver(built)

    def _own_solver(self, built: BuiltProblem):
        """This controller's QP (linear models) or IPOPT NLP solver, ``None`` on the ``'rti'`` path."""
        import casadi as ca  # imported here: loading a scenario must not pay for casadi

        if self.model.linear:
            with quiet_stdout():  # qpOASES prints its licence banner on construction
                return ca.qpsol("buavc_mpc", QP_SOLVER, built.problem, QP_OPTIONS[QP_SOLVER])
        if self.config.solver == "ipopt":
            return ca.nlpsol("buavc_mpc", "ipopt", built.problem, {
                "print_time": False, "error_on_fail": False,
                "ipopt": {"print_level": 0, "sb": "yes", "max_iter": self.config.max_iter, "tol": 1e-6,
                          "acceptable_tol": 1e-4, "acceptable_iter": 2, "warm_start_init_point": "yes",
                          "mu_init": 1e-3, "mu_strategy": "adaptive", "warm_start_bound_push": 1e-9,
                          "warm_start_mult_bound_push": 1e-9},
            })
        return None

    # ------------------------------------------------------------------ per-step solve
    def cell_parameters(self, A: np.ndarray, b: np.ndarray, valid: np.ndarray, position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One robot's cell as ``(M, d)``, ``(M,)`` parameters: its valid rows (for the casadi
        solvers, built for ``M = max_constraints``, the ``M`` tightest at ``position`` if there
        are more), padded with ``0·p ≤ 1``. The ``'rti'`` path takes every valid row: its QP
        drops the rows no admissible plan reaches by itself (:mod:`.rti`)."""
        rows = np.flatnonzero(valid)
        M, d = self.config.max_constraints if self._solver is not None else max(len(rows), 1), self.model.dim
        if len(rows) > M:
            slack = b[rows] - A[rows] @ position
            rows = rows[np.argsort(slack)[:M]]
        Ap = np.zeros((M, d))
        bp = np.ones(M)
        Ap[: len(rows)] = A[rows]
        bp[: len(rows)] = b[rows]
        return Ap, bp

    def plan(self, robot: int, state: np.ndarray, goal: np.ndarray, A: np.ndarray, b: np.ndarray) -> PlanResult:
        """Solve robot ``robot``'s problem from ``state`` toward ``goal`` in the cell ``(A, b)``
        (as :meth:`cell_parameters` gives it). A plan counts as in the cell when its inputs,
        simulated with the model's own step, keep every predicted position in the cell;
        nonlinear models without one apply the least-violating plan of :class:`~.rti.CondensedSQP`."""
        z0 = self._initial_guess(robot, state)
        if self._solver is None:
            return self._plan_rti(robot, state, goal, A, b, z0)
        result = self._plan_exact(robot, state, goal, A, b, z0)
        if result.in_cell or self._problem.sqp is None:
            return result
        return self._plan_rti(robot, state, goal, A, b, z0)  # IPOPT found no in-cell plan: the SQP as recovery

    def _plan_exact(self, robot: int, state: np.ndarray, goal: np.ndarray, A: np.ndarray, b: np.ndarray,
                    z0: np.ndarray) -> PlanResult:
        """:meth:`plan` with the casadi solver (qpOASES for linear models, IPOPT otherwise); the
        previous plan, shifted by one step, when the solution leaves the cell and it does not."""
        m, N = self.model, self.config.horizon
        p = np.concatenate([state, goal, A.T.ravel(), b - CELL_MARGIN])  # casadi reshape is column-major
        with quiet_stdout() if self._first_solve else contextlib.nullcontext():  # and on first use
            sol = self._solver(x0=z0, p=p, lbx=self._problem.lbz, ubx=self._problem.ubz, lbg=self._problem.lbg, ubg=self._problem.ubg, lam_g0=self._lam_g[robot])
        self._first_solve = False
        z = np.asarray(sol["x"]).ravel()
        U = z[m.nx * (N + 1) :].reshape(N, m.nu)
        positions = self.rollout(state, U)[:, : m.dim] if np.all(np.isfinite(z)) else None
        if positions is not None and np.all(positions[1:] @ A.T <= b + _CELL_TOL):
            self._warm[robot] = z
            self._lam_g[robot] = np.asarray(sol["lam_g"]).ravel()
            return PlanResult(U[0], positions, True, U)
        # the previous plan, shifted by one step, is still a valid plan if it stays in the new cell
        shifted = z0[m.nx * (N + 1) :].reshape(N, m.nu)
        positions = self.rollout(state, shifted)[:, : m.dim]
        if np.all(np.isfinite(self._warm[robot])) and np.all(positions[1:] @ A.T <= b + _CELL_TOL):
            self._warm[robot] = z0
            return PlanResult(shifted[0], positions, True, shifted)
        self._warm[robot] = np.nan
        self._lam_g[robot] = 0.0
        return PlanResult(None, None, False)

    def _plan_rti(self, robot: int, state: np.ndarray, goal: np.ndarray, A: np.ndarray, b: np.ndarray,
                  z0: np.ndarray) -> PlanResult:
        """:meth:`plan` with :class:`~.rti.CondensedSQP` from the shifted previous inputs; when
        that finds no in-cell plan although the estimate lies in its cell, a second start from
        the braking manoeuvre (a linearization point that stops in time). Without an in-cell
        plan the least-violating one is applied."""
        m, N = self.model, self.config.horizon
        reference = z0[m.nx * (N + 1):].reshape(N, m.nu)
        result = self._sqp_solve(state, goal, A, b, reference)
        if not result.in_cell and np.all(A @ state[: m.dim] <= b):
            second = self._sqp_solve(state, goal, A, b, self.fallback_inputs(state))
            if second.in_cell or second.violation < result.violation:
                result = second
        X = self.rollout(state, result.inputs)
        self._warm[robot] = np.concatenate([X.ravel(), result.inputs.ravel()])
        self._lam_g[robot] = 0.0
        return PlanResult(result.inputs[0], X[:, : m.dim], result.in_cell, result.inputs)

    def _sqp_solve(self, state: np.ndarray, goal: np.ndarray, A: np.ndarray, b: np.ndarray, reference: np.ndarray) -> SQPResult:
        """:meth:`~.rti.CondensedSQP.solve` with the noise band, shrunk linearly to 0 within one
        plan's reach of the goal (so that a goal near a face stays reachable)."""
        band = self.band * min(1.0, float(np.linalg.norm(goal - state[: self.model.dim])) / self.reach)
        return self._problem.sqp.solve(state, goal, A, b, reference, margin=CELL_MARGIN, tolerance=_CELL_TOL, band=band)

    def fallback_inputs(self, state: np.ndarray) -> np.ndarray:
        """Inputs ``(N, nu)`` of the model's safe fallback applied in closed loop from ``state``
        over the horizon (the brake of the quadrotor, zero for the unicycle)."""
        m, x = self.model, state
        U = np.empty((self.config.horizon, m.nu))
        for k in range(self.config.horizon):
            U[k] = m.fallback(x[None])[0]
            x = np.asarray(self._problem.step(x, U[k])).ravel()
        return U

    def rollout(self, state: np.ndarray, U: np.ndarray) -> np.ndarray:
        """States ``(N+1, nx)`` reached from ``state`` under the inputs ``U (N, nu)`` with the
        model's discrete step (the simulator's equations, compiled once): a plan is accepted
        only if these positions lie in the cell (a converged solve, or an unconverged one
        whose inputs are nevertheless safe)."""
        return np.asarray(self._problem.rollout(state, U.T)).T

    def _initial_guess(self, robot: int, state: np.ndarray) -> np.ndarray:
        """The previous plan shifted by one step (first solve: hold the current state, zero input)."""
        m, N = self.model, self.config.horizon
        prev = self._warm[robot]
        if not np.all(np.isfinite(prev)):
            return np.concatenate([np.tile(state, N + 1), np.zeros(m.nu * N)])
        X = prev[: m.nx * (N + 1)].reshape(N + 1, m.nx)
        U = prev[m.nx * (N + 1) :].reshape(N, m.nu)
        X = np.vstack([state, X[2:], X[-1:]])
        # a model with a rest set continues with the zero input, which holds it there
        U = np.vstack([U[1:], np.zeros((1, m.nu)) if m.rest is not None else U[-1:]])
        return np.concatenate([X.ravel(), U.ravel()])

    def control(self, states: np.ndarray, goals: np.ndarray, A: np.ndarray, b: np.ndarray, valid: np.ndarray, *, arrived: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
        """Controls ``(n, nu)`` for all robots of this model (one solve per robot).

        ``states (n, nx)`` are the robots' state estimates, ``goals (n, d)``, cells
        ``A (n, M', d)``, ``b (n, M')``, ``valid (n, M')``. ``arrived`` robots keep solving (their
        plans hold them at their goal inside their cell, so a neighbour's cell can push them
        aside); their steps are not counted as fallbacks.
        Returns the controls and ``{"plans": (n, N+1, d) the in-cell plans, NaN where none,
        "fallback": (n,) bool, no in-cell plan, "recovery": (n,) bool, of those the robots that
        apply the least-violating plan (the others brake), "goals": the working goals}``.
        """
        m, N = self.model, self.config.horizon
        n = len(states)
        positions = states[:, : m.dim]
        working = self._working_goals(positions, goals, arrived)
        controls = m.fallback(states)
        plans = np.full((n, N + 1, m.dim), np.nan)
        fallback, recovery = np.ones(n, bool), np.zeros(n, bool)
        todo = np.ones(n, bool) if arrived is None else ~arrived
        for i in range(n):
            Ai, bi = self.cell_parameters(A[i], b[i], valid[i], positions[i])
            result = self.plan(i, states[i], working[i], Ai, bi)
            if result.control is not None:
                controls[i] = result.control
            if result.in_cell:
                plans[i], fallback[i] = result.positions, False
            recovery[i] = result.control is not None and not result.in_cell
        self.infeasible += fallback & todo
        return controls, {"plans": plans, "fallback": fallback & todo, "recovery": recovery & todo, "goals": working}

    def _working_goals(self, positions: np.ndarray, goals: np.ndarray, arrived) -> np.ndarray:
        return self.rotation.working_goals(positions, goals, arrived)
