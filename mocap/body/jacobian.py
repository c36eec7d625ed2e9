"""Derivatives of posed points with respect to the pose, along the twist kinematic chain.

Linearising each exponential (Eq. 8), a point X attached to limb k moves by

    dX = dv + dw x X + sum_{d in chain(k)} dtheta_d  w_d' x (X - q_d')

where (dv, dw) is a world-frame increment of the global twist (applied on the left:
exp(hat(dxi)) exp(hat(xi_0))), and w_d', q_d' are the axis and a point of DOF d's twist in
the current pose: its rest twist carried by the transform of everything before it in the
chain (the parent joint's transform and the joint's earlier DOFs).
"""

from __future__ import annotations

import numpy as np

from mocap.body.model import BodyModel
from mocap.body.twists import hat, revolute_exp, se3_exp


def dof_frames(body: BodyModel, axes: np.ndarray, joints_rest: np.ndarray,
               chi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Current world axes (Dj, 3) and points (Dj, 3) of the revolute DOFs, and the joint
    transforms (J, 4, 4), for one pose chi (D,)."""
    parents, dof_joint = body.parents, body.dof_joint
    root = se3_exp(np.asarray(chi[:6], np.float64))
    E = revolute_exp(axes.astype(np.float64), joints_rest[dof_joint].astype(np.float64),
                     np.asarray(chi[6:], np.float64))
    J = len(parents)
    G = np.empty((J, 4, 4))
    pre = np.empty((len(dof_joint), 4, 4))
    local_done: dict[int, np.ndarray] = {}
    by_joint: dict[int, list[int]] = {}
    for d, j in enumerate(dof_joint):
        by_joint.setdefault(int(j), []).append(d)
    for j in range(J):
        base = root if parents[j] < 0 else G[parents[j]]
        T = base
        for d in by_joint.get(j, []):
            pre[d] = T
            T = T @ E[d]
        G[j] = T
        local_done[j] = T
    w = np.einsum("dab,db->da", pre[:, :3, :3], axes)
    q = np.einsum("dab,db->da", pre[:, :3, :3], joints_rest[dof_joint]) + pre[:, :3, 3]
    return w, q, G


def ancestors(parents: np.ndarray) -> np.ndarray:
    """(J, J) bool: A[k, j] = joint j is joint k or one of its ancestors."""
    J = len(parents)
    A = np.eye(J, dtype=bool)
    for k in range(J):
        p = parents[k]
        while p >= 0:
            A[k, p] = True
            p = parents[p]
    return A


def point_jacobians(body: BodyModel, points: np.ndarray, limbs: np.ndarray, w: np.ndarray,
                    q: np.ndarray) -> np.ndarray:
    """dX/d(dv, dw, dtheta) for posed points X (N, 3) attached to limbs (N,) -> (N, 3, D)."""
    N, D = len(points), body.num_dofs
    Jac = np.zeros((N, 3, D))
    Jac[:, :, :3] = np.eye(3)
    Jac[:, :, 3:6] = -hat(points)                                  # dw x X = -X x dw
    moves = ancestors(body.parents)[limbs][:, body.dof_joint]      # (N, Dj)
    vel = np.cross(w[None], points[:, None, :] - q[None])          # (N, Dj, 3)
    Jac[:, :, 6:] = np.where(moves[..., None], vel, 0.0).transpose(0, 2, 1)
    return Jac
