import numpy as np

from mocap.body.kinematics import chain_transforms, posed_joints
from mocap.body.lbs import lbs, lbs_apply, lbs_basis
from mocap.body.twists import se3_exp, so3_exp


def rigid(R, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def rot_about(axis, point, theta):
    """Rotation about an axis through a point, composed by hand: translate, rotate, back."""
    R = so3_exp(np.asarray(axis, float) * theta)
    return rigid(np.eye(3), point) @ rigid(R, np.zeros(3)) @ rigid(np.eye(3), -np.asarray(point))


def test_twist_chain_matches_composing_rigid_transforms_by_hand():
    # root -> a (2 DOFs) -> b (1 DOF); joint b has no DOF of its own but follows a
    parents = np.array([-1, 0, 1, 2])
    joints = np.array([[0, 0, 1.0], [0.2, 0, 1.0], [0.2, 0, 0.5], [0.2, 0, 0.1]])
    dof_joint = np.array([1, 1, 2])
    axes = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 0, 0]])
    root = np.array([[0.1, -0.2, 0.3, 0.2, -0.1, 0.5]])
    ang = np.array([[0.4, -0.7, 1.1]])
    G = chain_transforms(parents, dof_joint, axes, joints, root, ang)
    G0 = se3_exp(root[0])
    G1 = G0 @ rot_about(axes[0], joints[1], 0.4) @ rot_about(axes[1], joints[1], -0.7)
    G2 = G1 @ rot_about(axes[2], joints[2], 1.1)
    np.testing.assert_allclose(G[0], np.stack([G0, G1, G2, G2]), atol=1e-12)
    # a joint's position is moved by its parents only: joint 2 = G1 applied to its rest point
    J = posed_joints(G, joints)[0]
    np.testing.assert_allclose(J[2], (G1 @ np.append(joints[2], 1.0))[:3], atol=1e-12)


def test_lbs_fast_path_equals_reference_and_identity_returns_rest():
    rng = np.random.default_rng(1)
    V, J, P = 50, 4, 6
    W = rng.uniform(size=(V, J))
    W /= W.sum(1, keepdims=True)
    rest = rng.normal(size=(V, 3))
    T = se3_exp(rng.normal(size=(P, J, 6)))
    fast = lbs_apply(lbs_basis(W, rest), T)
    ref = lbs(W, rest, T)
    by_hand = np.einsum("vj,pjab,vb->pva", W, T[:, :, :3, :], np.c_[rest, np.ones(V)])
    np.testing.assert_allclose(fast, by_hand, atol=1e-12)
    np.testing.assert_allclose(ref, by_hand, atol=1e-12)
    ident = np.broadcast_to(np.eye(4), (2, J, 4, 4))
    np.testing.assert_allclose(lbs_apply(lbs_basis(W, rest), ident), np.stack([rest] * 2), atol=1e-12)
