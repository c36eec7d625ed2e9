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
