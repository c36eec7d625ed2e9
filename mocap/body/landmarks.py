"""Landmarks: 3D points attached to bones (joints, limb ends, head top, chest), posed by
forward kinematics. They are the markers of Canton-Ferrer et al. 2010 and the keypoints of
2D detectors.

A landmark is attached to one joint's rigid transform G_j (not skinned) at a rest-pose point
given either as that joint's (or another joint's) rest position, as the midpoint of several
joints' rest positions (``between``: e.g. the base of the neck between the clavicles), as
a mesh vertex (the vertex nearest a direction from the joint, chosen once on the mean body),
or as the centroid of the vertices of the joint's part (``centroid``: e.g. the centre of the
head), all linear in the shape.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mocap.body.model import BodyModel, ShapedBody


@dataclass(frozen=True)
class Landmark:
    """name; joint whose transform carries it; rest point: ``at`` joint, the mean of the
    ``between`` joints, ``vertex`` index, or the mean of ``vertices``."""

    name: str
    joint: str
    at: str | None = None
    vertex: int | None = None
    between: tuple[str, ...] = ()
    vertices: tuple[int, ...] = ()

    def rest_point(self, model: BodyModel, joints: np.ndarray, verts: np.ndarray) -> np.ndarray:
        """The rest point from rest joints (..., J, 3) and vertices (..., V, 3) -> (..., 3)."""
        if self.at is not None:
            return joints[..., model.joint_index(self.at), :]
        if self.between:
            return joints[..., [model.joint_index(n) for n in self.between], :].mean(axis=-2)
        if self.vertices:
            return verts[..., list(self.vertices), :].mean(axis=-2)
        return verts[..., self.vertex, :]


# The default set: the 15 HumanEva evaluation joints plus head top, chest, hands and toes.
DEFAULT_LANDMARKS: tuple[Mapping, ...] = (
    {"name": "pelvis", "joint": "pelvis", "at": "pelvis"},
    {"name": "thorax", "joint": "thorax", "at": "thorax"},
    {"name": "head", "joint": "head", "at": "head"},
    {"name": "head_top", "joint": "head", "extreme": [0, 0, 1]},
    {"name": "chest", "joint": "thorax", "extreme": [0, -1, 0]},
    {"name": "l_shoulder", "joint": "l_clavicle", "at": "l_shoulder"},
    {"name": "l_elbow", "joint": "l_shoulder", "at": "l_elbow"},
    {"name": "l_wrist", "joint": "l_elbow", "at": "l_wrist"},
    {"name": "l_hand", "joint": "l_wrist", "extreme": [1, 0, -1]},
    {"name": "r_shoulder", "joint": "r_clavicle", "at": "r_shoulder"},
    {"name": "r_elbow", "joint": "r_shoulder", "at": "r_elbow"},
    {"name": "r_wrist", "joint": "r_elbow", "at": "r_wrist"},
    {"name": "r_hand", "joint": "r_wrist", "extreme": [-1, 0, -1]},
    {"name": "l_hip", "joint": "pelvis", "at": "l_hip"},
    {"name": "l_knee", "joint": "l_hip", "at": "l_knee"},
    {"name": "l_ankle", "joint": "l_knee", "at": "l_ankle"},
    {"name": "l_toe", "joint": "l_ankle", "extreme": [0, -1, 0]},
    {"name": "r_hip", "joint": "pelvis", "at": "r_hip"},
    {"name": "r_knee", "joint": "r_hip", "at": "r_knee"},
    {"name": "r_ankle", "joint": "r_knee", "at": "r_ankle"},
    {"name": "r_toe", "joint": "r_ankle", "extreme": [0, -1, 0]},
)


class LandmarkSet:
    """Resolved landmarks of a body model; ``positions(shaped, chi) -> (P, L, 3)``."""

    def __init__(self, model: BodyModel, entries: Sequence[Mapping] = DEFAULT_LANDMARKS):
        self.model = model
        mean_verts, mean_joints = model.rest(np.zeros(model.num_shape))
        items = []
        for e in entries:
            name, joint = str(e["name"]), str(e["joint"])
            j = model.joint_index(joint)
            if "at" in e:
                model.joint_index(str(e["at"]))
                items.append(Landmark(name, joint, at=str(e["at"])))
            elif "between" in e:
                names = tuple(str(n) for n in e["between"])
                for n in names:
                    model.joint_index(n)
                items.append(Landmark(name, joint, between=names))
            elif "vertex" in e:
                v = int(e["vertex"])
                if not 0 <= v < model.num_vertices:
                    raise ValueError(f"landmark '{name}': vertex {v} out of range")
                items.append(Landmark(name, joint, vertex=v))
            elif "extreme" in e:
                # the vertex of this joint's part furthest along a direction
                d = np.asarray(e["extreme"], float)
                mask = model.part_labels == j
                cand = np.flatnonzero(mask)
                v = int(cand[np.argmax((mean_verts[cand] - mean_joints[j]) @ d)])
                items.append(Landmark(name, joint, vertex=v))
            elif e.get("centroid"):
                part = tuple(int(v) for v in np.flatnonzero(model.part_labels == j))
                if not part:
                    raise ValueError(f"landmark '{name}': joint '{joint}' has no vertices")
                items.append(Landmark(name, joint, vertices=part))
            else:
                raise ValueError(f"landmark '{name}' needs 'at', 'between', 'vertex', 'extreme' "
                                 "or 'centroid'")
        self.landmarks = tuple(items)
        self.names = tuple(lm.name for lm in items)
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"duplicate landmark names in {self.names}")
        self.joint = np.array([model.joint_index(lm.joint) for lm in items])

    def __len__(self) -> int:
        return len(self.landmarks)

    def rest_points(self, shaped: ShapedBody) -> np.ndarray:
        """Rest positions (L, 3) for a shaped body."""
        pts = np.empty((len(self), 3), dtype=shaped.rest_vertices.dtype)
        for i, lm in enumerate(self.landmarks):
            pts[i] = lm.rest_point(self.model, shaped.rest_joints, shaped.rest_vertices)
        return pts

    def from_transforms(self, transforms: np.ndarray, rest_points: np.ndarray) -> np.ndarray:
        """Posed landmarks from joint transforms (P, J, 4, 4) and rest points (L, 3) -> (P, L, 3)."""
        G = transforms[:, self.joint]                                   # (P, L, 4, 4)
        return (G[..., :3, :3] @ rest_points[..., None])[..., 0] + G[..., :3, 3]

    def positions(self, shaped: ShapedBody, chi: np.ndarray) -> np.ndarray:
        """Landmarks of a batch of poses chi (P, D) -> (P, L, 3), without skinning the mesh."""
        from mocap.body.kinematics import chain_transforms

        chi = np.atleast_2d(np.asarray(chi, dtype=self.model.dtype))
        m = self.model
        G = chain_transforms(m.parents, m.dof_joint, shaped.axes, shaped.rest_joints,
                             chi[:, :6], chi[:, 6:])
        return self.from_transforms(G, self.rest_points(shaped))
