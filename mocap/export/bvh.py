"""BVH export (written with ``bvhio``): mocap's skeleton hierarchy, one rotation per joint.

Offsets are the rest skeleton of the run's final shape (metres, scale 1: Blender imports it
at human size with its default scale); the root has position channels (absolute, root
OFFSET 0) and every joint ``Zrotation Xrotation Yrotation`` (intrinsic ZXY, degrees). The
rest pose (all rotations 0) is mocap's rest A-pose. Axes: Y up (``axes.BVH_FROM_WORLD``).
Joint positions recomputed from the file by forward kinematics equal the run's joints.
"""

from __future__ import annotations

from pathlib import Path

import bvhio
import numpy as np
from pyglm import glm

from mocap.export.axes import BVH_FROM_WORLD, points_to, quaternions_from_rotations, rotations_to
from mocap.export.motion import Motion

ROOT_CHANNELS = ["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"]
JOINT_CHANNELS = ["Zrotation", "Xrotation", "Yrotation"]
END_SITE_M = 0.1           # length of the end-site bones (head, hands, feet)


def local_rotations(motion: Motion) -> np.ndarray:
    """Rotation of each joint relative to its parent, in BVH axes: (F, J, 3, 3)."""
    R = rotations_to(BVH_FROM_WORLD, motion.joint_rotations)
    par = motion.joint_parents
    local = R.copy()
    nonroot = par >= 0
    local[:, nonroot] = np.swapaxes(R[:, par[nonroot]], -1, -2) @ R[:, nonroot]
    return local


def write_bvh(motion: Motion, path: str | Path) -> Path:
    path = Path(path)
    par, names = motion.joint_parents, motion.joint_names
    rest = points_to(BVH_FROM_WORLD, motion.rest_joints)
    root_pos = points_to(BVH_FROM_WORLD, motion.joints[:, 0])
    quats = quaternions_from_rotations(local_rotations(motion).reshape(-1, 3, 3))  # x, y, z, w
    quats = quats.reshape(motion.num_frames, len(names), 4)
    nodes: list[bvhio.BvhJoint] = []
    for j, name in enumerate(names):
        offset = (0.0, 0.0, 0.0) if par[j] < 0 else tuple(rest[j] - rest[par[j]])
        node = bvhio.BvhJoint(name, glm.vec3(*offset))
        node.Channels = list(ROOT_CHANNELS if par[j] < 0 else JOINT_CHANNELS)
        if par[j] >= 0:
            nodes[par[j]].Children.append(node)
        nodes.append(node)
    for j, node in enumerate(nodes):
        if not node.Children:
            bone = rest[j] - rest[par[j]] if par[j] >= 0 else np.array([0.0, 1.0, 0.0])
            node.EndSite = glm.vec3(*(END_SITE_M * bone / max(np.linalg.norm(bone), 1e-9)))
        for f in range(motion.num_frames):
            x, y, z, w = quats[f, j]
            pos = glm.vec3(*root_pos[f]) if par[j] < 0 else glm.vec3(node.Offset)
            node.Keyframes.append(bvhio.Pose(pos, glm.quat(w, x, y, z)))
    roots = [n for j, n in enumerate(nodes) if par[j] < 0]
    if len(roots) != 1:
        raise ValueError(f"BVH needs one root joint, the skeleton has {len(roots)}")
    bvhio.writeBvh(str(path), bvhio.BvhContainer(roots[0], motion.num_frames, 1.0 / motion.fps), percision=7)
    return path
