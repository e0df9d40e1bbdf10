"""B-UAVC geometry in R³ (and any low dimension): exact projection onto a polytope cell,
ε-shadow planes of boxes with yaw whose position is uncertain, and workspace bounds
with height (Zhu et al. 2022, Sec. 4 and appendix A; ``docs/theory/buavc.md``).

A cell is a padded half-space array, as everywhere in :mod:`robofleet.avoidance`:
unit normals ``A (N, M, d)``, offsets ``b (N, M)`` and a mask ``valid (N, M)``; robot
``i``'s cell is ``{p : A[i, m]·p ≤ b[i, m] for every valid m}``.
"""

from __future__ import annotations

from itertools import combinations, product

import numpy as np

_FEAS_TOL = 1e-9
_CHUNK = 128


# ----------------------------------------------------------------------------------------
# exact projection onto a polytope
# ----------------------------------------------------------------------------------------
def project_onto_polytope(points: np.ndarray, A: np.ndarray, b: np.ndarray, valid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Euclidean projection of each point onto its robot's cell, exactly, in any dimension d ≤ 3.

    The projection of ``g`` onto ``{x : A x ≤ b}`` lies in the relative interior of one
    face, whose affine hull is cut out by at most ``d`` linearly independent active
    constraints ``S``; there it equals the projection onto ``{x : A_S x = b_S}``,
    ``x = g − A_Sᵀ (A_S A_Sᵀ)⁻¹ (A_S g − b_S)``. Every active set of size ``0 … d`` is
    tried at once (vectorized) and the nearest *feasible* candidate is returned: it is
    the projection, because every feasible candidate is at least as far as the optimum
    and the optimum is among the candidates (KKT of the convex QP).

    Complexity ``O(N · C(M, ≤d) · M · d)``; meant for the cells of this package (M ≲ 30).

    Parameters
    ----------
    points : (N, d) goals to project
    A, b, valid : the cells, ``(N, M, d)``, ``(N, M)``, ``(N, M)`` (``valid`` defaults to all)

    Returns
    -------
    projection : (N, d) the closest cell point (the input point where the cell is empty)
    feasible : (N,) bool, False where the cell is empty
    """
    g = np.asarray(points, dtype=float)
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    valid = np.ones(b.shape, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    out = np.empty_like(g)
    ok = np.empty(len(g), dtype=bool)
    for start in range(0, len(g), _CHUNK):
        sl = slice(start, start + _CHUNK)
        out[sl], ok[sl] = _project_chunk(g[sl], A[sl], b[sl], valid[sl])
    return out, ok


def _project_chunk(g, A, b, valid):
    n, m, d = A.shape
    cand = [g[:, None, :]]
    for size in range(1, min(d, m) + 1):
        subsets = np.array(list(combinations(range(m), size)), dtype=np.intp)
        cand.append(_affine_projections(g, A, b, valid, subsets))
    cand = np.concatenate(cand, axis=1)  # (n, C, d)
    slack = np.einsum("nmd,ncd->ncm", A, cand) - b[:, None, :]
    feasible = np.all((slack <= _FEAS_TOL * (1 + np.abs(b[:, None, :]))) | ~valid[:, None, :], axis=2)
    feasible &= np.all(np.isfinite(cand), axis=2)
    dist = np.where(feasible, np.linalg.norm(cand - g[:, None, :], axis=2), np.inf)
    best = np.argmin(dist, axis=1)
    found = np.isfinite(dist[np.arange(n), best])
    proj = cand[np.arange(n), best]
    return np.where(found[:, None], proj, g), found


def _affine_projections(g, A, b, valid, subsets):
    """Projections of ``g`` onto ``{A_S x = b_S}`` for every subset ``S`` (rows of ``subsets``)."""
    AS = A[:, subsets, :]  # (n, C, k, d)
    bS = b[:, subsets]  # (n, C, k)
    gram = np.einsum("nckd,ncld->nckl", AS, AS)
    k = subsets.shape[1]
    det = np.linalg.det(gram) if k > 1 else gram[..., 0, 0]
    usable = np.all(valid[:, subsets], axis=2) & (np.abs(det) > 1e-10)
    gram = np.where(usable[..., None, None], gram, np.eye(k))
    resid = np.einsum("nckd,nd->nck", AS, g) - bS
    lam = np.linalg.solve(gram, resid[..., None])[..., 0]
    x = g[:, None, :] - np.einsum("nckd,nck->ncd", AS, lam)
    return np.where(usable[..., None], x, np.nan)


# ----------------------------------------------------------------------------------------
# ε-shadow planes of boxes with yaw (appendix A, Theorem 1)
# ----------------------------------------------------------------------------------------
def shadow_radius(epsilon: float, dim: int) -> float:
    """Radius ``√(χ²_d⁻¹(1 − ε))`` of the whitened displacement ball (appendix A, Lemma 1)."""
    from scipy.stats import chi2  # imported on use: scipy.stats alone takes most of a second to load

    return float(np.sqrt(chi2.ppf(1.0 - epsilon, dim)))


def box_axes(sizes: np.ndarray, yaws: np.ndarray) -> np.ndarray:
    """Matrices ``(O, 3, 3)`` mapping the unit cube ``[−1, 1]³`` onto each box (minus its centre).

    Column ``k`` is half the box's ``k``-th side along its yawed axis (yaw about z).
    """
    sizes = np.asarray(sizes, dtype=float)
    c, s = np.cos(yaws), np.sin(yaws)
    zero, one = np.zeros_like(c), np.ones_like(c)
    rot = np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)], -2)
    return rot * (0.5 * sizes)[:, None, :]


def whitening(cov: np.ndarray) -> np.ndarray:
    """``Σ^{-1/2}`` for covariances ``(..., d, d)``; the identity for a zero covariance
    (a known obstacle), and a tiny ridge ``1e-9·tr Σ`` for a singular, non-zero one."""
    cov = np.asarray(cov, dtype=float)
    d = cov.shape[-1]
    trace = np.trace(cov, axis1=-2, axis2=-1)
    zero = trace <= 0
    ridge = np.where(zero, 1.0, 1e-9 * trace)[..., None, None] * np.eye(d)
    w, v = np.linalg.eigh(np.where(zero[..., None, None], np.eye(d), cov + ridge))
    return np.einsum("...ij,...j,...kj->...ik", v, 1.0 / np.sqrt(w), v)


def closest_points_on_boxes(points: np.ndarray, origins: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Closest point of each parallelepiped ``{o + M z : z ∈ [−1, 1]³}`` to each point.

    ``points (N, 3)``, ``origins (O, 3)``, ``axes (O, 3, 3)`` → ``(N, O, 3)``. Exact: the
    27 face patterns (each coordinate free, −1 or +1) are solved as least-squares
    problems at once and the nearest candidate that lies in the box wins.
    """
    patterns = np.array(list(product((0, -1, 1), repeat=3)), dtype=float)  # (27, 3)
    free = patterns == 0
    rel = points[:, None, :] - origins[None]  # (N, O, 3)
    rhs_base = rel[:, None] - np.einsum("oij,pj->poi", axes, patterns)[None]  # (N, 27, O, 3)
    P = free[:, None, :, None] * free[:, None, None, :]  # (27, 1, 3, 3)
    MtM = np.einsum("oki,okj->oij", axes, axes)[None]  # (1, O, 3, 3)
    lhs = np.where(P, MtM, 0.0) + np.where(free, 0.0, 1.0)[:, None, :, None] * np.eye(3)
    rhs = np.einsum("oki,npok->npoi", axes, rhs_base) * free[None, :, None, :]
    z_free = np.linalg.solve(np.broadcast_to(lhs, (len(points), *lhs.shape)), rhs[..., None])[..., 0]
    z = np.where(free[None, :, None, :], z_free, patterns[None, :, None, :])
    inside = np.all(np.abs(z) <= 1 + 1e-12, axis=-1)
    cand = origins[None, None] + np.einsum("oij,npoj->npoi", axes, z)
    dist = np.where(inside, np.linalg.norm(cand - points[:, None, None, :], axis=-1), np.inf)
    best = np.argmin(dist, axis=1)  # (N, O)
    return np.take_along_axis(cand, best[:, None, :, None], axis=1)[:, 0]


def box_shadow_planes(points: np.ndarray, centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray, obstacle_cov: np.ndarray, epsilon: float) -> tuple[np.ndarray, np.ndarray]:
    """Separating planes between robot estimates and the ε-shadows of 3D boxes.

    Notes ``buavc.md`` steps 1–3 (appendix A): whiten with ``W = Σ_o^{-1/2}``; grow the
    whitened box by the ball of radius ``r = √(χ²₃⁻¹(1 − ε))`` (Lemma 1: the whitened
    displacement stays in it with probability ``1 − ε``, Theorem 1: the grown set is an
    ε-shadow); take the max-margin plane between the whitened estimate ``q`` and the
    grown box — normal ``n = (c* − q)/‖c* − q‖`` with ``c*`` the closest box point —
    shifted to touch the grown box: ``n·x ≤ n·c* − r``; map back with ``x = W p``.
    If ``q`` lies inside the box, ``n`` points to the box centre and the plane touches
    the grown box's far side of the support (``n·x ≤ min_box n·y − r``).

    Parameters
    ----------
    points : (N, 3) robot position estimates
    centers, sizes : (O, 3) box centres and side lengths
    yaws : (O,) box yaw angles [rad]
    obstacle_cov : (O, 3, 3) or (3, 3) covariance of each box's position
    epsilon : shadow probability ε

    Returns
    -------
    a : (N, O, 3) unit normals; robot side ``a·p ≤ b``
    b : (N, O)
    (Not yet tightened by the buffer β of the robot's own uncertainty.)
    """
    p = np.asarray(points, dtype=float)
    centers = np.asarray(centers, dtype=float)
    cov = np.broadcast_to(np.asarray(obstacle_cov, dtype=float), (len(centers), 3, 3))
    W = whitening(cov)  # (O, 3, 3)
    known = np.trace(cov, axis1=-2, axis2=-1) <= 0
    radius = np.where(known, 0.0, shadow_radius(epsilon, 3))
    q = np.einsum("oij,nj->noi", W, p)  # whitened robot point per obstacle
    origin = np.einsum("oij,oj->oi", W, centers)
    axes = np.einsum("oij,ojk->oik", W, box_axes(sizes, np.asarray(yaws, dtype=float)))
    closest = np.stack([closest_points_on_boxes(q[:, o], origin[o : o + 1], axes[o : o + 1])[:, 0] for o in range(len(centers))], axis=1) if len(centers) else np.zeros((len(p), 0, 3))
    gap = closest - q
    dist = np.linalg.norm(gap, axis=-1)
    to_centre = origin[None] - q
    n = np.where((dist > 1e-12)[..., None], gap, to_centre) / np.maximum(np.where(dist > 1e-12, dist, np.linalg.norm(to_centre, axis=-1)), 1e-300)[..., None]
    corner_signs = np.array(list(product((-1, 1), repeat=3)), dtype=float)
    corners = origin[:, None, :] + np.einsum("okj,cj->ock", axes, corner_signs)  # (O, 8, 3)
    support = np.min(np.einsum("noi,oci->noc", n, corners), axis=-1)
    offset = np.where(dist > 1e-12, np.einsum("noi,noi->no", n, closest), support) - radius[None]
    normal = np.einsum("oij,noj->noi", W, n)
    scale = np.linalg.norm(normal, axis=-1)
    return normal / scale[..., None], offset / scale


def workspace_box_planes(lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ``2d`` half-spaces ``±e_k·p ≤ ±bound`` of an axis-aligned workspace box (height included in 3D)."""
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    eye = np.eye(len(lo))
    return np.concatenate([eye, -eye]), np.concatenate([hi, -lo])
