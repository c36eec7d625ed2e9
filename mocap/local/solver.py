"""Pose from point-line correspondences by linearised twists (Zhang et al. 2013, Eq. 7-9).

Each correspondence pairs a model point X_i (posed, attached to limb k_i) with a 3D ray
given as a Plücker line (d_i, m_i), d_i unit. The error of Eq. 6 is e_i = X_i x d_i - m_i,
whose norm is the distance of X_i from the ray. With the first-order expansion of every
exponential (Eq. 8), X_i + J_i delta, the error becomes e_i - [d_i]x J_i delta: linear in
delta = (dv, dw, dtheta). One Gauss-Newton step solves the weighted least squares (Eq. 9)
with a small Levenberg damping, then updates the pose exactly: the global twist as
exp(hat(dxi)) exp(hat(xi_0)), the angles additively, clipped to the joint limits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocap.body.jacobian import ancestors, point_jacobians
from mocap.body.model import BodyModel
from mocap.body.twists import hat, se3_exp, se3_log
from mocap.local.normal_equations import accumulate, active_dofs, compiled_available
from mocap.local.posing import apply_delta_compiled

# True: the reference path without the compiled normal equations (benchmarks/bench_speed.py
# --compare times both)
LEGACY = False


@dataclass(frozen=True)
class PointLines:
    """N correspondences: points (N, 3) posed model points, limbs (N,) joint index,
    d (N, 3) unit directions and m (N, 3) moments of the rays, weights (N,)."""

    points: np.ndarray
    limbs: np.ndarray
    d: np.ndarray
    m: np.ndarray
    weights: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


def merge(parts: list[PointLines]) -> PointLines:
    """The correspondences of ``parts`` in one set (empty parts dropped)."""
    parts = [p for p in parts if len(p)]
    if not parts:
        z = np.zeros((0, 3))
        return PointLines(z, np.zeros(0, int), z, z, np.zeros(0))
    return PointLines(*(np.concatenate([getattr(p, f) for p in parts])
                        for f in ("points", "limbs", "d", "m", "weights")))


@dataclass(frozen=True)
class StepResult:
    chi: np.ndarray
    delta: np.ndarray
    ok: bool
    reason: str = ""
    rms_before: float = 0.0     # weighted RMS point-line distance (m) before the step


def point_line_residuals(points: np.ndarray, d: np.ndarray, m: np.ndarray) -> np.ndarray:
    """e = X x d - m, (N, 3)."""
    return np.cross(points, d) - m


def linear_system(body: BodyModel, corr: PointLines, w: np.ndarray, q: np.ndarray,
                  free: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stacked residuals e0 (3N,), matrix A (3N, D) with e(delta) = e0 + A delta, weights (3N,).

    A = -[d]x J (J from :func:`point_jacobians`), assembled column block by column block
    without the (N, 3, D) Jacobian: for the global twist -[d]x and [d]x [X]x = X d^T - (d.X) I;
    for revolute DOF j (axis w_j through q_j, moving the point's limb)
    -d x (w_j x (X - q_j)) = -w_j (d.(X - q_j)) + (X - q_j)(d.w_j).
    """
    if LEGACY:
        return linear_system_reference(body, corr, w, q, free)
    X = np.asarray(corr.points, np.float64)
    d = np.asarray(corr.d, np.float64)
    N, D = len(X), body.num_dofs
    A = np.zeros((N, 3, D))
    # dv block: -[d]x
    A[:, 0, 1], A[:, 0, 2] = d[:, 2], -d[:, 1]
    A[:, 1, 0], A[:, 1, 2] = -d[:, 2], d[:, 0]
    A[:, 2, 0], A[:, 2, 1] = d[:, 1], -d[:, 0]
    # dw block: X d^T - (d.X) I
    dX = np.einsum("na,na->n", d, X)
    A[:, :, 3:6] = X[:, :, None] * d[:, None, :]
    for k in range(3):
        A[:, k, 3 + k] -= dX
    # revolute DOFs, zero where the DOF does not move the point's limb
    moves = _moves(body)[corr.limbs]                                   # (N, Dj) 0 / 1
    a = (dX[:, None] - d @ q.T) * moves                               # d.(X - q_j)
    b = (d @ w.T) * moves                                             # d.w_j
    for k in range(3):                                                # row k of each block
        A[:, k, 6:] = (X[:, k, None] - q[None, :, k]) * b - w[None, :, k] * a
    if free is not None:
        A *= free[None, None, :]
    e0 = point_line_residuals(X, d, corr.m)
    return e0.reshape(-1), A.reshape(-1, D), np.repeat(corr.weights, 3)


def linear_system_reference(body: BodyModel, corr: PointLines, w: np.ndarray, q: np.ndarray,
                            free: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`linear_system` from the full Jacobian (N, 3, D): slower, obviously right (tests)."""
    Jac = point_jacobians(body, corr.points, corr.limbs, w, q)        # (N, 3, D)
    A = -hat(corr.d) @ Jac                                             # (N, 3, D)
    if free is not None:
        A = A * free[None, None, :]
    e0 = point_line_residuals(corr.points, corr.d, corr.m)
    return e0.reshape(-1), A.reshape(-1, body.num_dofs), np.repeat(corr.weights, 3)


_MOVES: dict[tuple[int, int], tuple] = {}


def _tree_tables(body: BodyModel) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Once per tree: (J, Dj) float 1 where revolute DOF j moves limb k (ancestors of k), and
    the same as per-limb DOF lists (:func:`~mocap.local.normal_equations.active_dofs`)."""
    key = (id(body.parents), id(body.dof_joint))
    cached = _MOVES.get(key)
    if cached is None or cached[0] is not body.parents or cached[1] is not body.dof_joint:
        table = ancestors(body.parents)[:, body.dof_joint].astype(np.float64)
        cached = _MOVES[key] = (body.parents, body.dof_joint, table, active_dofs(table))
    return cached[2], cached[3]


def _moves(body: BodyModel) -> np.ndarray:
    return _tree_tables(body)[0]


def apply_delta(body: BodyModel, chi: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """The pose after an increment: global twist composed on the left, angles added, limits."""
    out = np.asarray(chi, np.float64).copy()
    out[:6] = se3_log(se3_exp(delta[:6]) @ se3_exp(out[:6]))
    out[6:] += delta[6:]
    return np.clip(out, body.limits[:, 0], body.limits[:, 1])


def normal_equations(body: BodyModel, corr: PointLines, w: np.ndarray, q: np.ndarray,
                     free: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """H = A^T W A (D, D), g = A^T W e0 (D,) and the weighted RMS point-line distance of
    :func:`linear_system`'s system, compiled (:mod:`mocap.local.normal_equations`) or, without
    numba and on the LEGACY path, from the stacked matrix."""
    if not LEGACY and compiled_available():
        free_mask = np.ones(body.num_dofs, bool) if free is None else np.asarray(free) != 0
        H, g, sq = accumulate(corr.points, corr.d, corr.m, corr.weights, corr.limbs,
                              _tree_tables(body)[1], q, w, free_mask)
        return H, g, float(np.sqrt(sq / max(3.0 * float(np.sum(corr.weights)), 1e-12)))
    e0, A, wt = linear_system(body, corr, w, q, free)
    rms = float(np.sqrt((wt * e0**2).sum() / max(wt.sum(), 1e-12)))
    return A.T @ (wt[:, None] * A), A.T @ (wt * e0), rms


def bounded_solve(H: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                  max_rounds: int | None = None) -> np.ndarray:
    """The minimiser delta (D,) of 0.5 delta^T H delta + g^T delta (H (D, D) symmetric positive
    definite) within the box lo <= delta <= hi (D,) (+-inf: unbounded), by block principal
    pivoting (Judice and Pires 1994): every variable outside its bound is fixed at it, and every
    fixed one whose gradient points back into the box is freed, until neither happens (the KKT
    conditions hold). Without a bound reached it is the unconstrained solve; after
    ``max_rounds`` (default 2 D + 2) without settling, the last solve clipped to the box."""
    D = len(g)
    at_lo, at_hi = np.zeros(D, bool), np.zeros(D, bool)
    delta = np.zeros(D)
    for _ in range(2 * D + 2 if max_rounds is None else max_rounds):
        fixed = at_lo | at_hi
        delta = np.where(at_lo, lo, np.where(at_hi, hi, 0.0))
        f = ~fixed
        delta[f] = np.linalg.solve(H[np.ix_(f, f)], -(g[f] + H[np.ix_(f, fixed)] @ delta[fixed]))
        grad = H @ delta + g
        add_lo, add_hi = f & (delta < lo), f & (delta > hi)
        free_lo, free_hi = at_lo & (grad < 0), at_hi & (grad > 0)      # wants back inside
        if not (add_lo.any() or add_hi.any() or free_lo.any() or free_hi.any()):
            return delta
        at_lo, at_hi = (at_lo & ~free_lo) | add_lo, (at_hi & ~free_hi) | add_hi
    return np.clip(delta, lo, hi)


def gauss_newton_step(body: BodyModel, chi: np.ndarray, corr: PointLines, w: np.ndarray,
                      q: np.ndarray, damping: float = 1e-4, min_correspondences: int = 12,
                      max_step: float = 0.5, free: np.ndarray | None = None,
                      active_limits: bool = False) -> StepResult:
    """One linearised solve of Eq. 9. Skips the update (ok=False, with the reason) when there
    are too few correspondences, the system is degenerate, or the result is not finite.
    ``active_limits``: the joint angles' increments are solved within the joint limits
    (:func:`bounded_solve`: an angle that reaches its limit is held there and the other DOFs
    take up what it cannot give), not solved free and clipped after (the default)."""
    chi = np.asarray(chi, np.float64)
    if len(corr) < min_correspondences:
        return StepResult(chi, np.zeros_like(chi), False,
                          f"too few correspondences ({len(corr)} < {min_correspondences})")
    H, g, rms = normal_equations(body, corr, w, q, free)
    scale = np.maximum(np.diag(H), 1e-12)
    Hd = H + damping * np.diag(scale) + 1e-9 * np.eye(len(H))
    try:
        if active_limits:
            lo, hi = body.limits[:, 0] - chi, body.limits[:, 1] - chi
            lo[:6], hi[:6] = -np.inf, np.inf
            if free is not None:            # DOFs held: no increment
                lo, hi = np.where(free, lo, 0.0), np.where(free, hi, 0.0)
            delta = bounded_solve(Hd, g, np.minimum(lo, 0.0), np.maximum(hi, 0.0))
        else:
            delta = -np.linalg.solve(Hd, g)
    except np.linalg.LinAlgError:
        return StepResult(chi, np.zeros_like(chi), False, "singular normal equations", rms)
    if not np.all(np.isfinite(delta)):
        return StepResult(chi, np.zeros_like(chi), False, "non-finite update", rms)
    if free is not None:
        delta = np.where(free, delta, 0.0)
    big = np.abs(delta[3:]).max() if len(delta) > 3 else 0.0
    if big > max_step:                       # keep the linearisation valid
        delta = delta * (max_step / big)
    update = apply_delta if LEGACY or not compiled_available() else apply_delta_compiled
    return StepResult(update(body, chi, delta), delta, True, "", rms)
