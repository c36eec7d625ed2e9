"""The Gauss-Newton loop's small per-iteration pose maths compiled (numba): the DOF axes'
world frames (:func:`mocap.body.jacobian.dof_frames`'s w and q) and the pose update
(:func:`mocap.local.solver.apply_delta`), one call each instead of ~40 small numpy calls
(~0.8 ms of a ~6 ms iteration of the local step).

The same formulas and branches as the numpy functions (the compiled one-at-a-time twist maps
of :mod:`mocap.body.twists`; 4 x 4 rigid products as rotation and translation), so equal to
them to rounding (tested), not bit for bit: numpy's 4 x 4 products sum in another order.
"""

from __future__ import annotations

import numpy as np

from mocap.body.model import BodyModel
from mocap.compiled import HAVE_NUMBA, njit

if HAVE_NUMBA:
    from mocap.body.twists import hat_into, mul3_into, se3_exp_one, se3_log_one

    @njit(cache=True)
    def _rigid_mul(R1, t1, R2, t2, R, t):
        """(R, t) = (R1, t1) (R2, t2) (R, t must not alias the inputs)."""
        for i in range(3):
            for j in range(3):
                R[i, j] = R1[i, 0] * R2[0, j] + R1[i, 1] * R2[1, j] + R1[i, 2] * R2[2, j]
            t[i] = R1[i, 0] * t2[0] + R1[i, 1] * t2[1] + R1[i, 2] * t2[2] + t1[i]

    @njit(cache=True)
    def _dof_frames(parents, joint_start, joint_dofs, axes, points, chi, w, q):
        """w, q (Dj, 3): the world axis and point of every revolute DOF at pose chi (D,):
        the chain of :func:`mocap.body.jacobian.dof_frames` (joint j's DOFs
        joint_dofs[joint_start[j]:joint_start[j + 1]] in list order; axes, points (Dj, 3) in
        the rest frame)."""
        J = parents.shape[0]
        GR = np.empty((J, 3, 3))
        Gt = np.empty((J, 3))
        K = np.empty((3, 3))
        K2 = np.empty((3, 3))
        rootR = np.empty((3, 3))
        roott = np.empty(3)
        se3_exp_one(chi[:6], rootR, roott, K, K2)
        TR = np.empty((3, 3))
        Tt = np.empty(3)
        ER = np.empty((3, 3))
        Et = np.empty(3)
        NR = np.empty((3, 3))
        Nt = np.empty(3)
        for j in range(J):
            p = parents[j]
            if p < 0:
                TR[:, :] = rootR
                Tt[:] = roott
            else:
                TR[:, :] = GR[p]
                Tt[:] = Gt[p]
            for s in range(joint_start[j], joint_start[j + 1]):
                d = joint_dofs[s]
                # the DOF's frame before its own rotation
                for i in range(3):
                    w[d, i] = TR[i, 0] * axes[d, 0] + TR[i, 1] * axes[d, 1] + TR[i, 2] * axes[d, 2]
                    q[d, i] = (TR[i, 0] * points[d, 0] + TR[i, 1] * points[d, 1]
                               + TR[i, 2] * points[d, 2]) + Tt[i]
                # revolute_exp: R = I + s K + (1 - c) K^2, t = point - R point
                th = chi[6 + d]
                sn, cs = np.sin(th), np.cos(th)
                hat_into(axes[d, 0], axes[d, 1], axes[d, 2], K)
                mul3_into(K, K, K2)
                for i in range(3):
                    for k in range(3):
                        ER[i, k] = (1.0 if i == k else 0.0) + sn * K[i, k] + (1.0 - cs) * K2[i, k]
                for i in range(3):
                    Et[i] = points[d, i] - (ER[i, 0] * points[d, 0] + ER[i, 1] * points[d, 1]
                                            + ER[i, 2] * points[d, 2])
                _rigid_mul(TR, Tt, ER, Et, NR, Nt)
                TR[:, :] = NR
                Tt[:] = Nt
            GR[j] = TR
            Gt[j] = Tt

    @njit(cache=True)
    def _apply_delta(chi, delta, lo, hi, out):
        """out = the pose after ``delta``: the global twist se3_log(exp(delta) exp(chi)),
        the angles added, all clipped to [lo, hi]."""
        K = np.empty((3, 3))
        K2 = np.empty((3, 3))
        AR = np.empty((3, 3))
        At = np.empty(3)
        BR = np.empty((3, 3))
        Bt = np.empty(3)
        R = np.empty((3, 3))
        t = np.empty(3)
        ww = np.empty(3)
        se3_exp_one(delta[:6], AR, At, K, K2)
        se3_exp_one(chi[:6], BR, Bt, K, K2)
        _rigid_mul(AR, At, BR, Bt, R, t)
        se3_log_one(R, t, out[:6], ww, K, K2)
        for k in range(6, chi.shape[0]):
            out[k] = chi[k] + delta[k]
        for k in range(chi.shape[0]):
            out[k] = min(max(out[k], lo[k]), hi[k])


_TABLES: dict[int, tuple] = {}


def _joint_dofs(body: BodyModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Once per tree: parents (J,) int64, and each joint's DOFs in list order as offsets
    (J + 1,) into ids (Dj,)."""
    cached = _TABLES.get(id(body))
    if cached is None or cached[0] is not body:
        parents = np.asarray(body.parents, np.int64)
        dof_joint = np.asarray(body.dof_joint, np.int64)
        order = np.argsort(dof_joint, kind="stable")
        start = np.searchsorted(dof_joint[order], np.arange(len(parents) + 1))
        cached = _TABLES[id(body)] = (body, parents, start.astype(np.int64), order.astype(np.int64))
    return cached[1], cached[2], cached[3]


def dof_frames_compiled(body: BodyModel, axes: np.ndarray, joints_rest: np.ndarray,
                        chi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World axes (Dj, 3) and points (Dj, 3) of the revolute DOFs at pose chi (D,):
    :func:`mocap.body.jacobian.dof_frames`'s first two results, compiled (numba required)."""
    parents, start, ids = _joint_dofs(body)
    Dj = len(body.dof_joint)
    w, q = np.empty((Dj, 3)), np.empty((Dj, 3))
    _dof_frames(parents, start, ids, np.ascontiguousarray(axes, np.float64),
                np.ascontiguousarray(joints_rest[body.dof_joint], np.float64),
                np.ascontiguousarray(chi, np.float64), w, q)
    return w, q


def apply_delta_compiled(body: BodyModel, chi: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """:func:`mocap.local.solver.apply_delta` compiled (numba required)."""
    out = np.empty(len(chi))
    _apply_delta(np.ascontiguousarray(chi, np.float64), np.ascontiguousarray(delta, np.float64),
                 np.ascontiguousarray(body.limits[:, 0], np.float64),
                 np.ascontiguousarray(body.limits[:, 1], np.float64), out)
    return out
