"""Braking-safe real-time-iteration SQP for the B-UAVC MPC of nonlinear models (unicycle, quadrotor).

The NLP of :mod:`.mpc` is solved by Gauss–Newton SQP in the *condensed* form, following
the real-time iteration of Diehl, Bock and Schlöder (2005, "A real-time iteration scheme
for nonlinear optimization in optimal feedback control", SIAM J. Control Optim. 43(5)):
the reference is the previous plan shifted by one step (its last input replaced by zero,
the input that holds a robot at rest), and each iteration

1. rolls out the reference inputs ``ū`` with the model's discrete step (the simulator's
   equations) to the predicted positions ``p̄_k``, the limited state components ``w̄_k``
   (the quadrotor's horizontal velocity) and the final rest components ``r̄`` (the
   quadrotor's ``v_N, φ_N, θ_N``), with their exact sensitivities to ``u`` (casadi
   algorithmic differentiation);
2. solves one dense QP in the input increment ``δ`` (``nu·N`` variables) and the slacks
   ``s_1 … s_N, t_2 … t_N, s_w, s_r ≥ 0`` ::

       min   ‖g − p̄_N − J_N δ‖² / s  +  w_u/N · ‖ū + δ‖²  +  λ ‖δ‖²
             +  ρ_c Σ_k s_k  +  ρ_t Σ_k t_k  +  ρ_w s_w  +  ρ_r s_r  +  ε/2 ‖(s, t, s_w, s_r)‖²
       s.t.  A (p̄_k + J_k δ) ≤ b − margin − β_k + t_k + s_k,  0 ≤ t_k ≤ β_k   k = 1 … N   (cell)
             C (w̄_k + W_k δ) ≤ c + s_w                 k = 1 … N   (speed limit, an inscribed polygon)
             |r̄ + R δ| ≤ rest_tolerance + s_r                      (the plan ends at rest)
             u_lo ≤ ū + δ ≤ u_hi

   with ``s = max(‖g − p̂‖², 1)`` as in :mod:`.mpc` (Gauss–Newton Hessian), a
   Levenberg–Marquardt term ``λ ‖δ‖²`` (keeps the step where the linearization holds, and
   the Hessian well conditioned: DAQP needed ≈ 200 active-set iterations without it, ≈ 70
   with it), and the noise band ``β_1 = 0``, ``β_k = band`` for ``k ≥ 2`` (see below);
3. rolls out ``ū + δ`` exactly; the iterate is *in the cell* only if that rollout keeps
   every predicted position in the cell (the same check as for the IPOPT path; the band
   is not part of it). The reference itself counts as well when its rollout stays in the cell.

**Terminal rest set** (our addition, the terminal-set argument of Mayne et al. 2000,
"Constrained model predictive control: stability and optimality"). A plan that ends at
rest with level attitude (``v_N = 0, φ_N = θ_N = 0``) can be continued by the zero input,
which keeps the quadrotor where it is: the shifted plan, extended by zero, stays in the
old cell, and every applied plan contains a way to stop inside the cell the robot planned
in. Together with the speed limit (the team's ``v_max``) this bounds how far a plan
reaches, which the local box (only neighbours within ``R_loc`` shape the cell) needs.

**Exact penalty instead of infeasibility** (our addition). The slacks enter linearly with
weights ``ρ`` far above the multipliers of the hard problem (an exact ℓ1 penalty,
Fletcher 1987): when an in-cell plan of the linearized problem exists the QP returns it
with zero slacks; when none exists — the estimate lies outside its cell (the first
predicted position is fixed by the current velocity up to millimetres), or the robot is
too fast to stop in a cell that shrank — the QP returns the plan with the least summed
violation ``Σ_k max_j (a_jᵀ p_k − b_j)``, which re-enters the cell as early as the dynamics
allow. Such a plan is flagged (not in the cell) and applied instead of pure braking.

Only constraint rows that the increment can make active are passed to the QP: row ``a``
of stage ``k`` is dropped when ``a (p̄_k − …) + Σ_n |a J_k|_n · max(u_hi − ū, ū − u_lo)_n``
stays below its bound (the box of ``δ`` bounds how far the linearized position moves), so
the dropped rows hold for every admissible ``δ`` and the QP keeps its solution.

**Noise band** (our addition). The cell is rebuilt every step from fresh estimates, so the
shifted plan moves against the new cell by about the estimates' noise. Stages ``2 … N``
therefore pay ``ρ_t`` per metre for coming closer than ``band`` to a face (a soft
tightening, as in constraint-tightening stochastic MPC, e.g. Lorenzen et al. 2017, IEEE TAC
62(7), but traded against the goal instead of hard); stage 1, fixed by the velocity, keeps
the exact cell.

It stops at the first in-cell iterate (one QP per step when the shifted plan is good, the
real-time iteration proper), or after ``iterations`` QPs, and returns the last in-cell
iterate, else the least-violating one. The QP is solved
by DAQP (the dual active-set solver of Arnström, Bemporad and Axehill 2022, "A dual
active-set solver for embedded quadratic programming using recursive LDLᵀ updates",
IEEE TAC 67(8)) called directly from its Python package (the casadi ``conic`` wrapper of
the same solver costs ≈ 3 ms per call more).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..core.errors import ConfigError

INFINITY = 1e30  # DAQP's "no bound"
CELL_PENALTY = 1e4  # ρ_c per metre of cell violation (per stage)
LIMIT_PENALTY = 1e3  # ρ_w per m/s above the speed limit
REST_PENALTY = 1e3  # ρ_r per unit of final velocity / tilt
BAND_PENALTY = 1.0  # ρ_t per metre of noise band used (per stage)
SLACK_CURVATURE = 1e-2  # ε, keeps the Hessian positive definite in the slacks
STEP_WEIGHT = 1e-2  # λ of the Levenberg–Marquardt term λ‖δ‖²


@dataclass(frozen=True)
class StateLimit:
    """``C w ≤ c`` on the state components ``x[components]`` at every stage (``C (r, w)``, ``c (r,)``)."""

    components: slice
    normals: np.ndarray
    offsets: np.ndarray


@dataclass(frozen=True)
class SQPResult:
    """The inputs ``(N, nu)`` of a solve, whether their exact rollout keeps every predicted
    position in the cell, and the summed exact violation ``Σ_k max(0, max_j a_jᵀ p_k − b_j)``."""

    inputs: np.ndarray
    in_cell: bool
    violation: float


class CondensedSQP:
    """Gauss–Newton SQP on the inputs of one model (see the module docstring).

    Parameters
    ----------
    step : symbolic discrete step ``(x, u) -> x⁺`` (casadi column vectors)
    nx, nu, dim : int
        the state, input and position dimensions
    horizon : ``N``
    u_lo, u_hi : input bounds ``(nu,)``
    input_weight : ``w_u``
    iterations : most QPs per solve (1 = the pure real-time iteration)
    limits : :class:`StateLimit` rows kept at every stage (the quadrotor's speed limit)
    rest : state components that vanish at the end of the plan (the quadrotor's ``v, φ, θ``),
        within ``rest_tolerance``; ``None`` for none
    """

    def __init__(self, step: Callable, *, nx: int, nu: int, dim: int, horizon: int, u_lo: np.ndarray, u_hi: np.ndarray,
                 input_weight: float, iterations: int = 3, limits: tuple[StateLimit, ...] = (), rest: slice | None = None,
                 rest_tolerance: float = 0.02):
        import casadi as ca

        self._daqp = import_daqp()
        self.nx, self.nu, self.dim, self.N = nx, nu, dim, horizon
        self.u_lo, self.u_hi = np.tile(u_lo, horizon), np.tile(u_hi, horizon)
        self.weight = input_weight / horizon
        self.iterations = iterations
        self.limits, self.rest_tolerance = limits, rest_tolerance
        x0, u = ca.SX.sym("x0", nx), ca.SX.sym("u", nu * horizon)
        positions, limited, x = [], [], x0
        for k in range(horizon):
            x = step(x, u[k * nu:(k + 1) * nu])
            positions.append(x[:dim])
            limited.extend(x[lim.components] for lim in limits)
        final = x[rest] if rest is not None else ca.SX(0, 1)
        outputs = ca.vertcat(*positions, *limited, final)  # p_1 … p_N, then w_1 … w_N, then r
        self._n_limited = sum(lim.components.stop - lim.components.start for lim in limits)
        self._n_rest = final.numel()
        self._linearize = ca.Function("rti_linearize", [x0, u], [outputs, ca.jacobian(outputs, u)])
        self._positions = ca.Function("rti_positions", [x0, u], [ca.vertcat(*positions)])

    def solve(self, state: np.ndarray, goal: np.ndarray, A: np.ndarray, b: np.ndarray, reference: np.ndarray, *, margin: float,
              tolerance: float, band: float = 0.0) -> SQPResult:
        """The SQP from ``reference (N, nu)``: its last in-cell iterate (exact rollout from
        ``state`` within ``{p : A p ≤ b + tolerance}``), else its least-violating one.
        Padding rows (``A = 0``) are dropped."""
        used = np.any(A != 0, axis=1)
        A, b = A[used], b[used]
        u = np.clip(reference.ravel(), self.u_lo, self.u_hi)
        scale = max(float(np.sum((goal - state[: self.dim]) ** 2)), 1.0)
        violation = self.violation(state, u, A, b + tolerance)
        best, best_in, best_violation = u, violation == 0.0, violation  # the shifted plan itself is a candidate
        for _ in range(self.iterations):
            delta = self._increment(state, u, goal, A, b - margin, scale, band)
            if delta is None:
                break
            u = np.clip(u + delta, self.u_lo, self.u_hi)
            violation = self.violation(state, u, A, b + tolerance)
            if violation == 0.0:
                best, best_in, best_violation = u, True, 0.0
                break
            elif not best_in and violation < best_violation:
                best, best_violation = u, violation
        return SQPResult(best.reshape(self.N, self.nu), bool(best_in), float(best_violation))

    def violation(self, state: np.ndarray, u: np.ndarray, A: np.ndarray, b: np.ndarray) -> float:
        """``Σ_k max(0, max_j a_jᵀ p_k − b_j)`` over the exact rollout of ``u`` (0 = in the cell)."""
        if len(A) == 0:
            return 0.0
        positions = np.asarray(self._positions(state, u)).reshape(self.N, self.dim)
        return float(np.sum(np.maximum(np.max(positions @ A.T - b, axis=1), 0.0)))

    def _increment(self, state: np.ndarray, u: np.ndarray, goal: np.ndarray, A: np.ndarray, b: np.ndarray,
                   scale: float, band: float) -> np.ndarray | None:
        """The QP step ``δ`` of the module docstring, or ``None`` when DAQP fails."""
        d, N, n = self.dim, self.N, len(u)
        values, J = (np.asarray(v) for v in self._linearize(state, u))
        values = values.ravel()
        Jp = J[: N * d].reshape(N, d, n)
        width = np.maximum(self.u_hi - u, u - self.u_lo)
        bands = np.full(N, band)
        bands[0] = 0.0  # p_1 is fixed by the current velocity: the band starts at stage 2
        blocks = [self._cell_rows(values[: N * d].reshape(N, d), Jp, A, b, bands, width)]
        offset = N * d
        for lim in self.limits:
            w = lim.components.stop - lim.components.start
            blocks.append(self._limit_rows(values, J, offset, w, lim, width))
            offset += N * w
        if self._n_rest:
            blocks.append(self._rest_rows(values[offset:], J[offset:]))
        rows = np.vstack([blk[0] for blk in blocks])
        upper = np.concatenate([blk[1] for blk in blocks])
        n_slack = 2 * N + 2
        J_N = Jp[-1]
        gap = goal - values[(N - 1) * d: N * d]
        H = np.zeros((n + n_slack, n + n_slack))
        H[:n, :n] = 2.0 * (J_N.T @ J_N / scale + (self.weight + STEP_WEIGHT) * np.eye(n))
        H[n:, n:] = SLACK_CURVATURE * np.eye(n_slack)
        f = np.concatenate([2.0 * (-J_N.T @ gap / scale + self.weight * u),
                            np.full(N, CELL_PENALTY), np.full(N, BAND_PENALTY), [LIMIT_PENALTY, REST_PENALTY]])
        lower_bounds = np.concatenate([self.u_lo - u, np.zeros(n_slack)])
        upper_bounds = np.concatenate([self.u_hi - u, np.full(N, INFINITY), bands, [INFINITY, INFINITY]])
        if len(upper) == 0:
            rows, upper = np.zeros((1, n + n_slack)), np.ones(1)
        bupper = np.concatenate([upper_bounds, upper])
        blower = np.concatenate([lower_bounds, np.full(len(upper), -INFINITY)])
        sense = np.zeros(len(bupper), dtype=np.intc)
        z, _, flag, _ = self._daqp.solve(H, f, np.ascontiguousarray(rows), bupper, blower, sense)
        delta = np.asarray(z[:n])
        return delta if flag > 0 and np.all(np.isfinite(delta)) else None

    def _cell_rows(self, positions: np.ndarray, Jp: np.ndarray, A: np.ndarray, b: np.ndarray, bands: np.ndarray,
                   width: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``A J_k δ − s_k − t_k ≤ b − band_k − A p̄_k`` for the rows the increment can make active."""
        N, n = self.N, Jp.shape[2]
        sens = np.einsum("md,kdn->kmn", A, Jp)  # (N, M, n)
        upper = b[None, :] - bands[:, None] - positions @ A.T  # (N, M)
        active = rows_in_reach(sens, upper, width)
        stage = np.nonzero(active)[0]
        rows = np.zeros((len(stage), n + 2 * N + 2))
        rows[:, :n] = sens[active]
        rows[np.arange(len(stage)), n + stage] = -1.0
        rows[np.arange(len(stage)), n + N + stage] = -1.0
        return rows, upper[active]

    def _limit_rows(self, values: np.ndarray, J: np.ndarray, offset: int, w: int, lim: StateLimit,
                    width: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``C W_k δ − s_w ≤ c − C w̄_k`` at every stage, for the rows the increment can make active."""
        N, n = self.N, J.shape[1]
        current = values[offset: offset + N * w].reshape(N, w)
        sens = np.einsum("rw,kwn->krn", lim.normals, J[offset: offset + N * w].reshape(N, w, n))
        upper = lim.offsets[None, :] - current @ lim.normals.T
        active = rows_in_reach(sens, upper, width)
        rows = np.zeros((int(active.sum()), n + 2 * N + 2))
        rows[:, :n] = sens[active]
        rows[:, -2] = -1.0
        return rows, upper[active]

    def _rest_rows(self, final: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``±(r̄ + R δ) − s_r ≤ rest_tolerance``."""
        n, N = R.shape[1], self.N
        rows = np.zeros((2 * len(final), n + 2 * N + 2))
        rows[:, :n] = np.vstack([R, -R])
        rows[:, -1] = -1.0
        return rows, np.concatenate([self.rest_tolerance - final, self.rest_tolerance + final])


def rows_in_reach(sensitivity: np.ndarray, upper: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Which rows ``sensitivity · δ ≤ upper`` some increment with ``|δ_n| ≤ width_n`` can
    violate (``Σ_n |sensitivity_n| width_n > upper``); the others hold for every such δ."""
    return np.abs(sensitivity) @ width > upper


def import_daqp():
    """The ``daqp`` module, or a :class:`~robofleet.core.errors.ConfigError` naming the extra."""
    try:
        import daqp
    except ImportError:
        raise ConfigError("mpc.solver: 'rti' expected an installed daqp (pip install 'robofleet[mpc]'), received none") from None
    return daqp
