"""Axis conventions of the export formats. mocap's world: metres, Z up, right-handed.

``BVH_FROM_WORLD``: BVH files are Y-up; (x, y, z) -> (x, z, -y), which Blender's BVH importer
(defaults: forward -Z, up Y) maps back to exactly mocap's world axes, so a BVH opens standing
upright where the run put it. ``OPENSIM_FROM_WORLD``: OpenSim/Pose2Sim TRC files are Y-up;
(x, y, z) -> (y, z, x), the permutation Pose2Sim applies (``zup2yup``). glTF is Y-up (+Z
front): the same rotation as BVH. C3D keeps Z up (the usual lab convention).
"""

from __future__ import annotations

import numpy as np

BVH_FROM_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
OPENSIM_FROM_WORLD = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
GLTF_FROM_WORLD = BVH_FROM_WORLD


def points_to(frame: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 3x3 axis change to points (..., 3)."""
    return np.asarray(points, np.float64) @ frame.T


def rotations_to(frame: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Conjugate rotations (..., 3, 3) into the new axes: C R C^T."""
    return frame @ np.asarray(rotations, np.float64) @ frame.T


def quaternions_from_rotations(R: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` as (x, y, z, w) of rotation matrices ``R (..., 3, 3)``.

    The algorithm of ``scipy.spatial.transform.Rotation.from_matrix(R).as_quat()`` (scipy 1.17),
    in numpy, so that an export does not import scipy (issue 38: ~0.7 s of a BVH export's start):
    a matrix whose Gram matrix is not the identity to 1e-12 is first replaced by its nearest
    rotation (``U V^T`` of its SVD); then Markley's method takes the largest of the diagonal and
    the trace to build the quaternion, normalised. Same sign convention as scipy (not
    canonicalised: q and -q are one rotation)."""
    R = np.array(R, np.float64)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"rotations of shape {R.shape}: expected (..., 3, 3)")
    flat = R.reshape(-1, 3, 3)
    if np.any(np.linalg.det(flat) <= 0):
        raise ValueError("a rotation matrix with a non-positive determinant (not a rotation)")
    gram = flat @ np.swapaxes(flat, -1, -2)
    off = ~np.all(np.isclose(gram, np.eye(3), rtol=1e-5, atol=1e-12), axis=(-2, -1))
    if np.any(off):
        U, _, Vt = np.linalg.svd(flat[off])
        flat[off] = U @ Vt
    trace = flat[:, 0, 0] + flat[:, 1, 1] + flat[:, 2, 2]
    decision = np.stack([flat[:, 0, 0], flat[:, 1, 1], flat[:, 2, 2], trace], axis=-1)
    choice = np.argmax(decision, axis=-1)
    q = np.empty((len(flat), 4))
    t = choice == 3
    m = flat[t]
    q[t] = np.stack([m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1],
                     1 + trace[t]], axis=-1)
    for i in range(3):
        s = choice == i
        j, k = (i + 1) % 3, (i + 2) % 3
        m = flat[s]
        q[s, i] = 1 - trace[s] + 2 * m[:, i, i]
        q[s, j] = m[:, j, i] + m[:, i, j]
        q[s, k] = m[:, k, i] + m[:, i, k]
        q[s, 3] = m[:, k, j] - m[:, j, k]
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return q.reshape(*R.shape[:-2], 4)
