"""The exports' axis helpers: quaternions from rotation matrices without scipy."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocap.export.axes import quaternions_from_rotations


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_quaternions_equal_scipys_from_matrix(dtype):
    """Bit for bit scipy's Rotation.from_matrix(...).as_quat() on random rotations, on rotations
    rounded to float32 (not orthogonal to 1e-12: scipy's SVD projection first), and on the
    half-turns where each of Markley's four branches is taken."""
    R = Rotation.random(500, random_state=3).as_matrix().astype(dtype)
    turns = np.array([np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])])
    for M in (R, turns, R.reshape(50, 10, 3, 3)):
        want = Rotation.from_matrix(M.reshape(-1, 3, 3)).as_quat().reshape(*M.shape[:-2], 4)
        np.testing.assert_array_equal(quaternions_from_rotations(M), want)


def test_a_reflection_is_refused():
    with pytest.raises(ValueError, match="non-positive determinant"):
        quaternions_from_rotations(np.diag([1.0, 1.0, -1.0]))
