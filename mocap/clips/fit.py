"""Least squares of our body's pose (and one shape) on named points: the machinery shared by
the oracle (:func:`mocap.eval.mismatch.fit_oracle`) and retargeting
(:func:`mocap.clips.retarget.retarget`).

Points are the body's joints and landmarks of the catalogue (:mod:`mocap.body.catalogue`),
posed without skinning (:class:`PointFunction`). Targets are (F, S, 3) metres with weights
(F, S, 1) (0 where a target is missing). Joint limits are bounds on the angles; the shape's
coefficients lie within +-``shape_bound``.

- :func:`multistart_poses`: every frame's pose at a fixed shape from several starting points
  (the rest pose and random poses within the limits, the root from a Kabsch fit of the
  torso), keeping each frame's best; all frames in one block-diagonal trust-region problem.
- :func:`fit_shape`: shape and poses jointly on a few frames (dense trust region, forward
  differences: the oracle's); :func:`fit_shape_lm`: the same problem by Levenberg-Marquardt
  on the analytic pose Jacobian (retargeting's: ~10x faster, and it converges where the
  trust region stops at its evaluation budget).
- :func:`fit_poses`: every frame's pose at a fixed shape from given poses (block-diagonal).
- :func:`track_poses`: frame by frame, each frame starting from the previous one's pose
  (temporal warm start), by a bounded Levenberg-Marquardt on the analytic Jacobian of the
  twist chain (:func:`mocap.body.jacobian.point_jacobians`): ~1 ms a frame.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import block_diag

from mocap.body.dofs import resolve_axes
from mocap.body.jacobian import dof_frames, point_jacobians
from mocap.body.kinematics import chain_transforms, posed_joints
from mocap.body.model import BodyModel
from mocap.body.twists import se3_exp, se3_log

# our point names that move with the torso: the root's Kabsch start uses them
TORSO = ("pelvis", "mid_hip", "l_hip", "r_hip", "thorax", "spine", "neck", "neck_base", "l_shoulder",
         "r_shoulder")


class PointFunction:
    """Named points of the body (joints, and landmarks of the catalogue) as a function of shape
    and pose, without skinning: landmarks ride their joint's transform, their rest points
    linear in the shape (:func:`mocap.body.catalogue.rest_point_basis`)."""

    def __init__(self, body: BodyModel, names: Sequence[str]):
        from mocap.body.catalogue import landmarks_with, rest_point_basis

        self.body = body
        self.names = list(names)
        marks = landmarks_with(body, names)          # the catalogue's points among names
        self.is_joint = np.array([n in body.joint_names for n in names])
        self.index = np.array([body.joint_index(n) if j else marks.names.index(n)
                               for n, j in zip(names, self.is_joint, strict=True)], int)
        self.carrier = marks.joint
        d = body.data
        self.mean, self.basis = d.joints_mean.astype(np.float64), d.joints_basis.astype(np.float64)
        self.marks_mean, self.marks_basis = rest_point_basis(body, marks)
        # the joint whose transform carries each point
        self.carriers = np.where(self.is_joint, self.index, 0)
        if not self.is_joint.all():
            self.carriers[~self.is_joint] = self.carrier[self.index[~self.is_joint]]

    def rest(self, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rest joints (J, 3), DOF axes (Dj, 3) and the landmarks' rest points (S, 3) (rows of
        joint points unused) of shape alpha (K,)."""
        rest = self.mean + np.einsum("k,kjc->jc", alpha, self.basis)
        axes = resolve_axes(self.body.dofs, self.body.joint_names, rest)
        marks = np.zeros((len(self.index), 3))
        if not self.is_joint.all():
            k = self.index[~self.is_joint]
            marks[~self.is_joint] = self.marks_mean[k] + np.einsum("k,klc->lc", alpha, self.marks_basis[:, k])
        return rest, axes, marks

    def __call__(self, alpha: np.ndarray, chi: np.ndarray) -> np.ndarray:
        """alpha (K,), chi (P, D) -> (P, S, 3) float64."""
        b = self.body
        rest = self.mean + np.einsum("k,kjc->jc", alpha, self.basis)
        axes = resolve_axes(b.dofs, b.joint_names, rest)
        G = chain_transforms(b.parents, b.dof_joint, axes, rest, chi[:, :6], chi[:, 6:])
        out = np.empty((len(chi), len(self.index), 3))
        out[:, self.is_joint] = posed_joints(G, rest)[:, self.index[self.is_joint]]
        if not self.is_joint.all():
            k = self.index[~self.is_joint]
            R = self.marks_mean[k] + np.einsum("k,klc->lc", alpha, self.marks_basis[:, k])
            Gl = G[:, self.carrier[k]]
            out[:, ~self.is_joint] = (Gl[..., :3, :3] @ R[..., None])[..., 0] + Gl[..., :3, 3]
        return out


def kabsch(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """4x4 rigid transform taking src (N, 3) onto dst (N, 3) in the least-squares sense."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    U, _, Vt = np.linalg.svd((src - cs).T @ (dst - cd))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, cd - R @ cs
    return T


def pose_bounds(body: BodyModel) -> tuple[np.ndarray, np.ndarray]:
    """(D,), (D,): the joint limits as bounds (infinite for the root)."""
    lo = np.where(np.isfinite(body.limits[:, 0]), body.limits[:, 0], -np.inf)
    hi = np.where(np.isfinite(body.limits[:, 1]), body.limits[:, 1], np.inf)
    return lo, hi


def torso_points(names: Sequence[str]) -> list[int]:
    return [k for k, n in enumerate(names) if n in TORSO]


def root_start(fn: PointFunction, alpha: np.ndarray, angles: np.ndarray, targets: np.ndarray,
               valid: np.ndarray, torso: Sequence[int]) -> np.ndarray:
    """Poses (F, D) with the given angles (F, D-6) or (D-6,) and the root that puts the torso
    points (at least 3 valid; else all valid points) on the targets (F, S, 3) by Kabsch."""
    F, S = targets.shape[:2]
    chi = np.zeros((F, fn.body.num_dofs))
    chi[:, 6:] = angles
    posed = fn(alpha, chi)
    for f in range(F):
        use = [k for k in (torso if len(torso) >= 3 else range(S)) if valid[f, k]]
        if len(use) >= 3:
            chi[f, :6] = se3_log(kabsch(posed[f, use], targets[f, use]))
    return chi


def fit_poses(fn: PointFunction, alpha: np.ndarray, chi0: np.ndarray, target: np.ndarray, w: np.ndarray,
              lo_d: np.ndarray, hi_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every frame's pose at shape alpha from chi0 (F, D): one bounded trust-region problem,
    block-diagonal over frames. target (F, S, 3), w (F, S, 1) -> chi (F, D), cost (F,)."""
    F, D = chi0.shape
    S = target.shape[1]
    lo_f, hi_f = np.tile(lo_d, F), np.tile(hi_d, F)
    per_frame_blocks = block_diag([np.ones((S * 3, D))] * F).tocsr()   # frames are independent
    x0 = np.clip(chi0.ravel(), lo_f + 1e-9, hi_f - 1e-9)
    r = least_squares(lambda x: ((fn(alpha, x.reshape(F, D)) - target) * w).ravel(), x0,
                      bounds=(lo_f, hi_f), jac_sparsity=per_frame_blocks, method="trf", max_nfev=100)
    chi = r.x.reshape(F, D)
    cost = (((fn(alpha, chi) - target) * w) ** 2).sum(axis=(1, 2))
    return chi, cost


def multistart_poses(fn: PointFunction, alpha: np.ndarray, target: np.ndarray, w: np.ndarray,
                     targets_raw: np.ndarray, valid: np.ndarray, lo_d: np.ndarray, hi_d: np.ndarray,
                     torso: Sequence[int], starts: int, rng: np.random.Generator) -> np.ndarray:
    """Each frame's best pose (F, D) over ``starts`` starting points: the rest pose, then random
    poses within half the limits, each with the root from :func:`root_start` (on targets_raw
    (F, S, 3), the targets before zeroing the invalid ones)."""
    F, D = target.shape[0], fn.body.num_dofs
    lo_a, hi_a = np.clip(lo_d[6:], -np.pi, np.pi), np.clip(hi_d[6:], -np.pi, np.pi)
    best, best_cost = None, np.full(F, np.inf)
    for s in range(starts):
        angles = np.zeros(D - 6) if s == 0 else rng.uniform(lo_a, hi_a, (F, D - 6)) * 0.5
        chi, cost = fit_poses(fn, alpha, root_start(fn, alpha, angles, targets_raw, valid, torso),
                              target, w, lo_d, hi_d)
        better = cost < best_cost
        best = chi if best is None else np.where(better[:, None], chi, best)
        best_cost = np.where(better, cost, best_cost)
    return best


def fit_shape(fn: PointFunction, target: np.ndarray, w: np.ndarray, chi: np.ndarray, lo_d: np.ndarray,
              hi_d: np.ndarray, shape_bound: float, alpha0: np.ndarray | None = None,
              max_nfev: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Shape (K,) and poses (n, D) jointly on n frames: target (n, S, 3), w (n, S, 1), starting
    poses chi (n, D) and shape alpha0 (default the mean). Dense bounded trust region, forward
    differences (poses column by column across frames, then the shape); at most ``max_nfev``
    evaluations."""
    n, D = chi.shape
    S, K = target.shape[1], fn.body.num_shape
    alpha0 = np.zeros(K) if alpha0 is None else alpha0

    def joint_points(x):
        return fn(x[n * D:], x[:n * D].reshape(n, D))

    def joint_residual(x):
        return ((joint_points(x) - target) * w).ravel()

    def joint_jacobian(x, h=1e-6):
        base = joint_points(x)
        Jp = np.zeros((n, S * 3, n, D))
        for d in range(D):
            y = x.copy()
            y[d:n * D:D] += h
            Jp[np.arange(n), :, np.arange(n), d] = ((joint_points(y) - base) * w / h).reshape(n, S * 3)
        Js = np.zeros((n * S * 3, K))
        for k in range(K):
            y = x.copy()
            y[n * D + k] += h
            Js[:, k] = ((joint_points(y) - base) * w / h).ravel()
        return np.hstack([Jp.reshape(n * S * 3, n * D), Js])

    lo = np.r_[np.tile(lo_d, n), np.full(K, -shape_bound)]
    hi = np.r_[np.tile(hi_d, n), np.full(K, shape_bound)]
    x0 = np.clip(np.r_[chi.ravel(), alpha0], lo + 1e-9, hi - 1e-9)
    x = least_squares(joint_residual, x0, jac=joint_jacobian, bounds=(lo, hi), method="trf",
                      tr_solver="exact", max_nfev=max_nfev).x
    return x[n * D:], x[:n * D].reshape(n, D)


class ShapedPoints:
    """A :class:`PointFunction` at one shape, for one pose at a time: the points (S, 3) and
    their analytic Jacobian (S, 3, D) with respect to a left increment (dv, dw) of the root
    and the angles (:func:`mocap.body.jacobian.point_jacobians`)."""

    def __init__(self, fn: PointFunction, alpha: np.ndarray):
        self.fn = fn
        self.rest, self.axes, self.marks = fn.rest(np.asarray(alpha, np.float64))
        self.rest_points = np.where(fn.is_joint[:, None], self.rest[fn.carriers], self.marks)

    def points(self, chi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """chi (D,) -> points (S, 3) and the DOFs' current axes and points (for the Jacobian)."""
        w, q, G = dof_frames(self.fn.body, self.axes, self.rest, chi)
        Gc = G[self.fn.carriers]
        X = (Gc[:, :3, :3] @ self.rest_points[..., None])[..., 0] + Gc[:, :3, 3]
        return X, w, q

    def jacobian(self, X: np.ndarray, w: np.ndarray, q: np.ndarray) -> np.ndarray:
        return point_jacobians(self.fn.body, X, self.fn.carriers, w, q)


def _update(chi: np.ndarray, step: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    new = np.empty_like(chi)
    new[:6] = se3_log(se3_exp(step[:6]) @ se3_exp(chi[:6]))
    new[6:] = np.clip(chi[6:] + step[6:], lo[6:], hi[6:])
    return new


def solve_pose(sp: ShapedPoints, target: np.ndarray, w: np.ndarray, chi0: np.ndarray, lo: np.ndarray,
               hi: np.ndarray, iterations: int = 50, tol: float = 1e-5, step_tol: float = 1e-5,
               combine: np.ndarray | None = None) -> tuple[np.ndarray, float, int]:
    """One frame's pose: bounded Levenberg-Marquardt from chi0 (D,) on targets (S, 3) with
    weights w (S,); with ``combine`` (R, S), on targets (R, 3) for the rows ``combine @ points``
    (e.g. differences of points: segments), weights w (R,). The root moves by left increments,
    the angles are clipped to their limits (an angle at a limit whose gradient pushes it out
    stays put). Stops when an iteration lowers the cost by less than ``tol`` of itself or
    1e-10 m^2, or moves no coordinate by ``step_tol`` (rad or m). -> chi, cost, iterations."""
    def rows(X):
        return X if combine is None else combine @ X

    def jac(X, wa, qa):
        Jp = sp.jacobian(X, wa, qa)
        return Jp if combine is None else np.einsum("rs,scd->rcd", combine, Jp)

    chi = chi0.copy()
    chi[6:] = np.clip(chi[6:], lo[6:], hi[6:])
    X, wa, qa = sp.points(chi)
    r = ((rows(X) - target) * w[:, None]).ravel()
    cost = float(r @ r)
    lam = 1e-4
    D = len(chi)
    it = 0
    while it < iterations:
        it += 1
        Jm = (jac(X, wa, qa) * w[:, None, None]).reshape(-1, D)
        g = Jm.T @ r
        H = Jm.T @ Jm
        at_lo = np.r_[np.zeros(6, bool), chi[6:] <= lo[6:] + 1e-12] & (g > 0)
        at_hi = np.r_[np.zeros(6, bool), chi[6:] >= hi[6:] - 1e-12] & (g < 0)
        free = ~(at_lo | at_hi)
        Hf, gf = H[np.ix_(free, free)], g[free]
        improved = False
        while lam < 1e10:
            step = np.zeros(D)
            A = Hf + lam * (np.diag(np.diag(Hf)) + 1e-9 * np.eye(len(gf)))
            step[free] = np.linalg.solve(A, -gf)
            new = _update(chi, step, lo, hi)
            Xn, wn, qn = sp.points(new)
            rn = ((rows(Xn) - target) * w[:, None]).ravel()
            cn = float(rn @ rn)
            if cn < cost:
                improved = True
                lam = max(lam / 5.0, 1e-9)
                break
            lam *= 6.0
        if not improved:
            break
        done = cost - cn <= max(tol * cost, 1e-10) or np.abs(step).max() < step_tol
        chi, X, wa, qa, r, cost = new, Xn, wn, qn, rn, cn
        if done:
            break
    return chi, cost, it


def track_poses(fn: PointFunction, alpha: np.ndarray, target: np.ndarray, w: np.ndarray, chi0: np.ndarray,
                lo_d: np.ndarray, hi_d: np.ndarray, restart_mm: float = 40.0,
                torso: Sequence[int] = (), combine: np.ndarray | None = None,
                restart_target: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Poses (F, D) frame by frame at shape alpha, frame 0 from chi0 (D,), frame t from t-1's
    pose. target (F, S, 3), w (F, S) (or rows (F, R, 3), (F, R) of ``combine`` (R, S), see
    :func:`solve_pose`) -> chi (F, D), cost (F,). Where a frame's worst row stays over
    ``restart_mm`` off, it is solved again from the previous angles and from the rest angles,
    each with the root put on the torso by Kabsch (on ``restart_target`` (F, S, 3), default
    the targets), and the best is kept."""
    sp = ShapedPoints(fn, alpha)
    F, D = target.shape[0], fn.body.num_dofs
    points_target = target if restart_target is None else restart_target
    chi = np.zeros((F, D))
    cost = np.zeros(F)
    prev = np.asarray(chi0, np.float64)
    for f in range(F):
        c, e, _ = solve_pose(sp, target[f], w[f], prev, lo_d, hi_d, combine=combine)
        X, _, _ = sp.points(c)
        Y = X if combine is None else combine @ X
        worst = np.max(np.linalg.norm(Y - target[f], axis=-1) * (w[f] > 0))
        if worst * 1e3 > restart_mm:
            valid = (w[f] > 0)[None] if combine is None else np.ones((1, points_target.shape[1]), bool)
            for angles in (c[6:], np.zeros(D - 6)):
                start = root_start(fn, alpha, angles, points_target[f][None], valid, torso)[0]
                c2, e2, _ = solve_pose(sp, target[f], w[f], start, lo_d, hi_d, combine=combine)
                if e2 < e:
                    c, e = c2, e2
        chi[f], cost[f] = c, e
        prev = c
    return chi, cost


def multistart_frames(fn: PointFunction, alpha: np.ndarray, target: np.ndarray, w: np.ndarray,
                      lo_d: np.ndarray, hi_d: np.ndarray, torso: Sequence[int], starts: int,
                      rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Each frame's best pose over ``starts`` starting points (the starts of
    :func:`multistart_poses`), each frame solved on its own by :func:`solve_pose`.
    target (F, S, 3), w (F, S) -> chi (F, D), cost (F,)."""
    sp = ShapedPoints(fn, alpha)
    F, D = target.shape[0], fn.body.num_dofs
    lo_a, hi_a = np.clip(lo_d[6:], -np.pi, np.pi), np.clip(hi_d[6:], -np.pi, np.pi)
    best, best_cost = np.zeros((F, D)), np.full(F, np.inf)
    for s in range(starts):
        angles = np.zeros((F, D - 6)) if s == 0 else rng.uniform(lo_a, hi_a, (F, D - 6)) * 0.5
        chi0 = root_start(fn, alpha, angles, target, w > 0, torso)
        for f in range(F):
            c, e, _ = solve_pose(sp, target[f], w[f], chi0[f], lo_d, hi_d)
            if e < best_cost[f]:
                best[f], best_cost[f] = c, e
    return best, best_cost


def fit_shape_lm(fn: PointFunction, target: np.ndarray, w: np.ndarray, chi: np.ndarray, lo_d: np.ndarray,
                 hi_d: np.ndarray, shape_bound: float, alpha0: np.ndarray | None = None,
                 iterations: int = 60, tol: float = 1e-7) -> tuple[np.ndarray, np.ndarray, float]:
    """Shape (K,) and poses (n, D) jointly on n frames, as :func:`fit_shape` but by a bounded
    Levenberg-Marquardt: the poses' Jacobians analytic (left root increments, see
    :func:`solve_pose`), the shape's by forward differences over all frames at once; the
    normal equations of all frames and the shape solved together. target (n, S, 3), w (n, S),
    chi (n, D) starting poses -> alpha, chi, cost. Stops when an iteration lowers the cost by
    less than ``tol`` of itself."""
    n, D = chi.shape
    S, K = target.shape[1], fn.body.num_shape
    alpha = np.zeros(K) if alpha0 is None else np.asarray(alpha0, np.float64)
    alpha = np.clip(alpha, -shape_bound, shape_bound)
    chi = chi.copy()
    chi[:, 6:] = np.clip(chi[:, 6:], lo_d[6:], hi_d[6:])
    W = w[..., None]
    lo = np.r_[np.tile(np.r_[np.full(6, -np.inf), lo_d[6:]], n), np.full(K, -shape_bound)]
    hi = np.r_[np.tile(np.r_[np.full(6, np.inf), hi_d[6:]], n), np.full(K, shape_bound)]
    root = np.tile(np.r_[np.ones(6, bool), np.zeros(D - 6, bool)], n)
    root = np.r_[root, np.zeros(K, bool)]

    def residual(a, c):
        return ((fn(a, c) - target) * W).ravel()

    def linearise(a, c, r, h=1e-6):
        sp = ShapedPoints(fn, a)
        Jm = np.zeros((n * S * 3, n * D + K))
        for f in range(n):
            X, wa, qa = sp.points(c[f])
            Jm[f * S * 3:(f + 1) * S * 3, f * D:(f + 1) * D] = (sp.jacobian(X, wa, qa) * W[f, :, :, None]
                                                                ).reshape(S * 3, D)
        for k in range(K):
            b = a.copy()
            b[k] += h
            Jm[:, n * D + k] = (residual(b, c) - r) / h
        return Jm

    def apply(a, c, step):
        new_c = np.stack([_update(c[f], step[f * D:(f + 1) * D], lo_d, hi_d) for f in range(n)])
        return np.clip(a + step[n * D:], -shape_bound, shape_bound), new_c

    r = residual(alpha, chi)
    cost = float(r @ r)
    lam = 1e-3
    x_now = np.r_[chi.ravel(), alpha]          # for the bound tests (angles and shape only)
    for _ in range(iterations):
        Jm = linearise(alpha, chi, r)
        g = Jm.T @ r
        H = Jm.T @ Jm
        x_now = np.r_[chi.ravel(), alpha]
        at_bound = ~root & (((x_now <= lo + 1e-12) & (g > 0)) | ((x_now >= hi - 1e-12) & (g < 0)))
        free = ~at_bound
        Hf, gf = H[np.ix_(free, free)], g[free]
        improved = False
        while lam < 1e10:
            step = np.zeros(len(g))
            step[free] = np.linalg.solve(Hf + lam * (np.diag(np.diag(Hf)) + 1e-9 * np.eye(len(gf))), -gf)
            a_new, c_new = apply(alpha, chi, step)
            r_new = residual(a_new, c_new)
            c_cost = float(r_new @ r_new)
            if c_cost < cost:
                improved = True
                lam = max(lam / 5.0, 1e-9)
                break
            lam *= 6.0
        if not improved:
            break
        done = cost - c_cost <= tol * cost
        alpha, chi, r, cost = a_new, c_new, r_new, c_cost
        if done:
            break
    return alpha, chi, cost
