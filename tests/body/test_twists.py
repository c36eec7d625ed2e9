import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from mocap.body.twists import (
    hat,
    invert_rigid,
    revolute_exp,
    revolute_twist,
    se3_exp,
    se3_log,
    so3_exp,
    so3_log,
    twist_hat,
)

rng = np.random.default_rng(0)


@pytest.mark.parametrize("dtype,tol", [(np.float64, 1e-12), (np.float32, 1e-5)])
def test_so3_exp_matches_scipy_rodrigues(dtype, tol):
    w = rng.normal(size=(50, 3)) * rng.uniform(0, 3, size=(50, 1))
    w[0] = 0.0
    w[1] = [1e-7, 0, 0]
    R = so3_exp(w.astype(dtype))
    assert R.dtype == dtype
    np.testing.assert_allclose(R, Rotation.from_rotvec(w).as_matrix(), atol=tol)


def test_hat_is_cross_product():
    a, b = rng.normal(size=(2, 10, 3))
    np.testing.assert_allclose((hat(a) @ b[..., None])[..., 0], np.cross(a, b), atol=1e-12)


def test_so3_log_inverts_exp_including_near_pi():
    w = rng.normal(size=(100, 3))
    w = w / np.linalg.norm(w, axis=1, keepdims=True) * rng.uniform(0, np.pi - 1e-3, (100, 1))
    w[0] = [np.pi, 0, 0]
    R = so3_exp(w)
    np.testing.assert_allclose(so3_exp(so3_log(R)), R, atol=1e-9)
    np.testing.assert_allclose(so3_log(R[1:]), w[1:], atol=1e-7)


def test_se3_exp_matches_matrix_exponential():
    xi = rng.normal(size=(30, 6))
    np.testing.assert_allclose(se3_exp(xi), expm_batch(twist_hat(xi)), atol=1e-10)


def expm_batch(A):
    return np.stack([expm(a) for a in A])


def test_se3_exp_is_exact_for_pure_translation():
    xi = np.zeros((4, 6))
    xi[:, :3] = rng.normal(size=(4, 3))
    T = se3_exp(xi)
    np.testing.assert_array_equal(T[:, :3, :3], np.broadcast_to(np.eye(3), (4, 3, 3)))
    np.testing.assert_array_equal(T[:, :3, 3], xi[:, :3])


def test_se3_log_inverts_exp():
    xi = rng.normal(size=(50, 6))
    w = xi[:, 3:]
    xi[:, 3:] = w / np.linalg.norm(w, axis=1, keepdims=True) * rng.uniform(0, 3.0, (50, 1))
    np.testing.assert_allclose(se3_log(se3_exp(xi)), xi, atol=1e-9)


def test_revolute_exp_is_rotation_about_axis_through_point():
    axis = rng.normal(size=(20, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    q = rng.normal(size=(20, 3))
    theta = rng.uniform(-3, 3, size=20)
    T = revolute_exp(axis, q, theta)
    np.testing.assert_allclose(T, se3_exp(revolute_twist(axis, q) * theta[:, None]), atol=1e-10)
    # the point on the axis is fixed; the rotation part is Rodrigues'
    np.testing.assert_allclose((T[:, :3, :3] @ q[..., None])[..., 0] + T[:, :3, 3], q, atol=1e-12)
    np.testing.assert_allclose(T[:, :3, :3], so3_exp(axis * theta[:, None]), atol=1e-12)


def test_invert_rigid():
    T = se3_exp(rng.normal(size=(10, 6)))
    np.testing.assert_allclose(invert_rigid(T) @ T, np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
