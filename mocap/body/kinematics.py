"""The twist kinematic chain (Zhang et al. 2013, Eq. 3-5; Murray, Li & Sastry 1994).

A pose is chi = (xi_0, theta): the global twist xi_0 = (v, omega) as 6 numbers, whose
exponential places the whole body, and one angle per revolute degree of freedom. Every
twist is expressed in the rest configuration, so the transform of joint j is the product of
exponentials along its chain (Eq. 4)

    G_j = exp(hat(xi_0)) * prod_{d in chain(j)} exp(theta_d hat(xi_d)),

which maps rest-pose points attached to joint j to their posed positions.
"""

from __future__ import annotations

import numpy as np

from mocap.body.twists import revolute_exp, se3_exp


def chain_transforms(parents: np.ndarray, dof_joint: np.ndarray, dof_axes: np.ndarray,
                     joints_rest: np.ndarray, root_twist: np.ndarray,
                     angles: np.ndarray) -> np.ndarray:
    """World transforms of every joint for a batch of poses.

    parents: (J,) parent index, -1 for the root, parents before children
    dof_joint: (D,) joint index of each revolute DOF; a joint's DOFs multiply in list order
    dof_axes: (D, 3) or (P, D, 3) unit axes in the rest body frame
    joints_rest: (J, 3) or (P, J, 3) rest joint positions (the twists' points)
    root_twist: (P, 6) global twist (v, omega); angles: (P, D) radians
    -> (P, J, 4, 4) rest-to-posed rigid transforms.
    """
    P, J = root_twist.shape[0], len(parents)
    pts = joints_rest[..., dof_joint, :]
    E = revolute_exp(dof_axes, pts, angles)                     # (P, D, 4, 4)
    local: list[np.ndarray | None] = [None] * J
    for d, j in enumerate(dof_joint):
        local[j] = E[:, d] if local[j] is None else local[j] @ E[:, d]
    out = np.empty((P, J, 4, 4), dtype=angles.dtype)
    root = se3_exp(root_twist.astype(angles.dtype, copy=False))
    for j in range(J):
        base = root if parents[j] < 0 else out[:, parents[j]]
        out[:, j] = base if local[j] is None else base @ local[j]
    return out


def posed_joints(transforms: np.ndarray, joints_rest: np.ndarray) -> np.ndarray:
    """Joint positions: G_j applied to rest joint j. (P, J, 4, 4), (J|P,J, 3) -> (P, J, 3)."""
    return (transforms[..., :3, :3] @ joints_rest[..., None])[..., 0] + transforms[..., :3, 3]
