"""Real-time-iteration SQP for the B-UAVC MPC of nonlinear models (unicycle, quadrotor).

The NLP of :mod:`.mpc` is solved by Gauss–Newton SQP in the *condensed* form, following
the real-time iteration of Diehl, Bock and Schlöder (2005, "A real-time iteration scheme
for nonlinear optimization in optimal feedback control", SIAM J. Control Optim. 43(5)):
the reference is the previous plan shifted by one step, and each iteration

1. rolls out the reference inputs ``ū`` with the model's discrete step (the simulator's
   equations) to the predicted positions ``p̄_k`` and their exact sensitivities
   ``J_k = ∂p_k/∂u`` (casadi algorithmic differentiation);
2. solves one dense QP in the input increment ``δ`` (``nu·N`` variables) ::

       min_δ  ‖g − p̄_N − J_N δ‖² / s  +  w_u/N · ‖ū + δ‖²
       s.t.   A (p̄_k + J_k δ) ≤ b − margin,   k = 1 … N     (every predicted position in the cell)
              u_lo ≤ ū + δ ≤ u_hi

   with ``s = max(‖g − p̂‖², 1)`` as in :mod:`.mpc` (Gauss–Newton Hessian);
3. rolls out ``ū + δ`` exactly; the iterate is a candidate only if that rollout stays in
   the cell (the same check as for the IPOPT path). The reference itself is a candidate
   too when its rollout stays in the cell (as the shifted plan is on the IPOPT path).

It stops at the first candidate whose increment is small, or after ``iterations`` QPs,
and returns the last candidate (``None`` if no iterate's rollout stayed in the cell).
The QP is solved by a dense solver through casadi's ``conic`` interface (DAQP, the
dual active-set solver of Arnström, Bemporad and Axehill 2022, by default; qpOASES, OSQP
selectable); one solver is built per number of used cell
rows, so padding rows never enter the QP.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..core.output import quiet_stdout

QP_OPTIONS = {
    "qpoases": {"printLevel": "none", "error_on_fail": False, "sparse": False},
    "daqp": {"error_on_fail": False},
    "osqp": {"osqp": {"verbose": False, "eps_abs": 1e-7, "eps_rel": 1e-7, "polish": False}, "error_on_fail": False},
}


class CondensedSQP:
    """Gauss–Newton SQP on the inputs of one model (see the module docstring).

    Parameters
    ----------
    step : symbolic discrete step ``(x, u) -> x⁺`` (casadi column vectors)
    nx, nu, dim : state, input and position dimensions
    horizon : ``N``
    u_lo, u_hi : input bounds ``(nu,)``
    input_weight : ``w_u``
    qp_solver : casadi ``conic`` plugin (one of :data:`QP_OPTIONS`)
    iterations : most QPs per solve (1 = the pure real-time iteration)
    terminal, terminal_bound : state components ``x_N[terminal]`` kept within ``± terminal_bound``
        (the quadrotor's final velocity: a robot that can stop inside its cell at the end of
        the horizon keeps a feasible plan next step, the terminal-set argument of Mayne et al.
        2000, "Constrained model predictive control: stability and optimality"); dropped for
        the solve when the QP with it is infeasible
    """

    def __init__(self, step: Callable, *, nx: int, nu: int, dim: int, horizon: int, u_lo: np.ndarray, u_hi: np.ndarray,
                 input_weight: float, qp_solver: str = "daqp", iterations: int = 3, terminal: slice | None = None,
                 terminal_bound: float = np.inf):
        import casadi as ca

        self.nx, self.nu, self.dim, self.N = nx, nu, dim, horizon
        self.u_lo, self.u_hi = np.tile(u_lo, horizon), np.tile(u_hi, horizon)
        self.weight = input_weight / horizon
        self.qp_solver, self.iterations = qp_solver, iterations
        x0, u = ca.SX.sym("x0", nx), ca.SX.sym("u", nu * horizon)
        states, x = [], x0
        for k in range(horizon):
            x = step(x, u[k * nu:(k + 1) * nu])
            states.append(x[:dim])
        positions = ca.vertcat(*states)  # (N·dim): p_1 … p_N, stage-major
        self._linearize = ca.Function("rti_linearize", [x0, u], [positions, ca.jacobian(positions, u)])
        final = x[terminal] if terminal is not None else ca.SX(0, 1)
        self._terminal = ca.Function("rti_terminal", [x0, u], [final, ca.jacobian(final, u)])
        self.terminal_bound = terminal_bound
        self._solvers: dict[int, object] = {}

    def _qp(self, rows: int):
        """The casadi ``conic`` for ``rows`` constraint rows (built on first use)."""
        import casadi as ca

        if rows not in self._solvers:
            n = self.nu * self.N
            spec = {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity.dense(rows, n)}
            with quiet_stdout():  # qpOASES prints its licence banner on construction
                self._solvers[rows] = ca.conic("rti_qp", self.qp_solver, spec, QP_OPTIONS[self.qp_solver])
        return self._solvers[rows]

    def solve(self, state: np.ndarray, goal: np.ndarray, A: np.ndarray, b: np.ndarray, reference: np.ndarray, *, margin: float,
              tolerance: float) -> np.ndarray | None:
        """Inputs ``(N, nu)`` whose exact rollout from ``state`` keeps every predicted position
        in ``{p : A p ≤ b + tolerance}``, starting from ``reference (N, nu)``; ``None`` if no
        iterate's rollout stays in the cell. Padding rows (``A = 0``) are dropped."""
        used = np.any(A != 0, axis=1)
        A, b = A[used], b[used]
        u = np.clip(reference.ravel(), self.u_lo, self.u_hi)
        scale = max(float(np.sum((goal - state[: self.dim]) ** 2)), 1.0)
        best = u.copy() if self._in_cell(state, u, A, b + tolerance) else None  # the shifted plan itself is a valid plan
        terminal = np.isfinite(self.terminal_bound)
        for _ in range(self.iterations):
            p_ref, J = (np.asarray(v) for v in self._linearize(state, u))
            p_ref = p_ref.ravel()
            extra = self._terminal_rows(state, u) if terminal else None
            delta = self._increment(u, p_ref, J, goal, A, b - margin, scale, extra)
            if delta is None and terminal:
                terminal = False
                delta = self._increment(u, p_ref, J, goal, A, b - margin, scale, None)
            if delta is None:
                break
            u = np.clip(u + delta, self.u_lo, self.u_hi)
            if self._in_cell(state, u, A, b + tolerance):
                best = u.copy()
                if np.max(np.abs(delta)) <= 1e-3:
                    break
        return None if best is None else best.reshape(self.N, self.nu)

    def _in_cell(self, state: np.ndarray, u: np.ndarray, A: np.ndarray, b: np.ndarray) -> bool:
        """Whether the exact rollout of ``u`` keeps every predicted position in ``A p ≤ b``."""
        positions = np.asarray(self._linearize(state, u)[0]).reshape(self.N, self.dim)
        return bool(np.all(positions @ A.T <= b))

    def _terminal_rows(self, state: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Linearized ``|x_N[terminal]| ≤ bound`` as rows ``G δ ≤ h``."""
        value, jac = (np.asarray(v) for v in self._terminal(state, u))
        value = value.ravel()
        return np.vstack([jac, -jac]), np.concatenate([self.terminal_bound - value, self.terminal_bound + value])

    def _increment(self, u: np.ndarray, p_ref: np.ndarray, J: np.ndarray, goal: np.ndarray, A: np.ndarray, b: np.ndarray,
                   scale: float, extra: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray | None:
        """The QP step ``δ`` of the module docstring, or ``None`` when the QP solver fails."""
        d, N = self.dim, self.N
        J_N = J[(N - 1) * d:]
        gap = goal - p_ref[(N - 1) * d:]
        H = 2.0 * (J_N.T @ J_N / scale + self.weight * np.eye(len(u)))
        g = 2.0 * (-J_N.T @ gap / scale + self.weight * u)
        # A_k J_k for every stage k, stacked: (N·M, nu·N)
        rows = np.einsum("md,kdn->kmn", A, J.reshape(N, d, -1)).reshape(N * len(A), -1)
        upper = (b[None, :] - p_ref.reshape(N, d) @ A.T).ravel()
        if extra is not None:
            rows, upper = np.vstack([rows, extra[0]]), np.concatenate([upper, extra[1]])
        if len(upper) == 0:
            rows, upper = np.zeros((1, len(u))), np.ones(1)
        solver = self._qp(len(upper))
        sol = solver(h=H, g=g, a=rows, lba=-np.inf, uba=upper, lbx=self.u_lo - u, ubx=self.u_hi - u)
        delta = np.asarray(sol["x"]).ravel()
        return delta if solver.stats()["success"] and np.all(np.isfinite(delta)) else None
