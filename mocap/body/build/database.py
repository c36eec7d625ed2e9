"""Sources of a database of registered rest-pose bodies.

``sample_anny``      adult bodies sampled from the ``anny`` package (torch; build extra only)
``load_mesh_folder`` any folder of registered meshes sharing one topology (.obj/.ply/.off/.stl)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

# The reduced skeleton: joint name, parent, and the anny bone whose head is the joint.
# Every anny bone is owned by the joint of its nearest ancestor-or-self listed here.
REDUCED_SKELETON: tuple[tuple[str, str | None, str], ...] = (
    ("pelvis", None, "root"),
    ("spine", "pelvis", "spine03"),
    ("thorax", "spine", "spine01"),
    ("neck", "thorax", "neck01"),
    ("head", "neck", "head"),
    ("l_clavicle", "thorax", "clavicle.L"),
    ("l_shoulder", "l_clavicle", "upperarm01.L"),
    ("l_elbow", "l_shoulder", "lowerarm01.L"),
    ("l_wrist", "l_elbow", "wrist.L"),
    ("r_clavicle", "thorax", "clavicle.R"),
    ("r_shoulder", "r_clavicle", "upperarm01.R"),
    ("r_elbow", "r_shoulder", "lowerarm01.R"),
    ("r_wrist", "r_elbow", "wrist.R"),
    ("l_hip", "pelvis", "upperleg01.L"),
    ("l_knee", "l_hip", "lowerleg01.L"),
    ("l_ankle", "l_knee", "foot.L"),
    ("r_hip", "pelvis", "upperleg01.R"),
    ("r_knee", "r_hip", "lowerleg01.R"),
    ("r_ankle", "r_knee", "foot.R"),
)


@dataclass(frozen=True)
class MeshDatabase:
    """Registered rest meshes of one topology (shapes in metres, body frame z up)."""

    vertices: np.ndarray                 # (N, V, 3)
    faces: np.ndarray                    # (F, 3)
    weights: np.ndarray | None = None    # (V, J) skinning weights, if the source has them
    joints: np.ndarray | None = None     # (N, J, 3) rest joints, if the source has them
    joint_names: tuple[str, ...] = ()
    joint_parents: np.ndarray | None = None
    description: str = ""


def load_mesh_folder(folder: str | Path) -> MeshDatabase:
    """All meshes of a folder, which must share one topology (same faces, same count)."""
    import trimesh

    folder = Path(folder)
    files = sorted(p for p in folder.iterdir()
                   if p.suffix.lower() in {".obj", ".ply", ".off", ".stl"})
    if len(files) < 3:
        raise ValueError(f"{folder}: need at least 3 registered meshes, found {len(files)}")
    verts, faces = [], None
    for p in files:
        m = trimesh.load(p, process=False, force="mesh")
        if faces is None:
            faces = np.asarray(m.faces)
        elif m.faces.shape != faces.shape or not np.array_equal(m.faces, faces):
            raise ValueError(f"{p}: topology differs from {files[0].name} "
                             f"(faces {m.faces.shape} vs {faces.shape})")
        verts.append(np.asarray(m.vertices, dtype=np.float64))
    return MeshDatabase(vertices=np.stack(verts), faces=faces.astype(np.int32),
                        description=f"{len(files)} registered meshes from {folder}")


def sample_anny(num_bodies: int, seed: int = 0, wide_fraction: float = 0.5) -> MeshDatabase:
    """Adult bodies from anny in the rest (bind) pose, on the reduced skeleton.

    Half (``1 - wide_fraction``) follow anny's calibrated adult phenotype distribution
    (SimpleShapeDistribution, morphological age 18-80); the rest draw gender, weight,
    muscle and proportions uniformly in [0, 1] (stature stays calibrated) for a wide range.
    Vertices are the rest vertices of anny's topology (13k, with the eye/mouth shells).
    """
    import torch
    from anny import Anny
    from anny.shape_distribution import SimpleShapeDistribution

    torch.manual_seed(seed)
    model = Anny(skinning_method="lbs")
    dist = SimpleShapeDistribution(
        model, morphological_age_distribution=torch.distributions.Uniform(
            torch.tensor(18.0, dtype=model.dtype), torch.tensor(80.0, dtype=model.dtype)))
    _, ph = dist.sample(num_bodies)
    n_wide = int(round(wide_fraction * num_bodies))
    for key in ("gender", "weight", "muscle", "proportions"):
        ph[key][:n_wide] = torch.rand(n_wide, dtype=model.dtype)
    verts, heads = [], []
    with torch.no_grad():
        for start in range(0, num_bodies, 50):
            sub = {k: v[start:start + 50] for k, v in ph.items()}
            out = model(phenotype_kwargs=sub)
            verts.append(out["rest_vertices"].numpy())
            heads.append(out["rest_bone_heads"].numpy())
    verts, heads = np.concatenate(verts), np.concatenate(heads)
    labels = list(model.bone_labels)
    parents = np.asarray(model.bone_parents)
    names = tuple(j[0] for j in REDUCED_SKELETON)
    from mocap.body.build.skeleton import nearest_owned_ancestor, reduce_weights

    defining = {labels.index(bone): i for i, (_, _, bone) in enumerate(REDUCED_SKELETON)}
    owner = nearest_owned_ancestor(parents, defining)
    weights = reduce_weights(model.dense_vertex_bone_weights.numpy(), owner, len(names))
    joints = heads[:, [labels.index(b) for _, _, b in REDUCED_SKELETON], :]
    joint_parents = np.array([-1 if p is None else names.index(p) for _, p, _ in REDUCED_SKELETON])
    # Body frame: feet on z = 0, pelvis above the origin.
    offset = np.stack([joints[:, 0, 0], joints[:, 0, 1], verts[..., 2].min(axis=1)], axis=1)
    verts = verts - offset[:, None, :]
    joints = joints - offset[:, None, :]
    return MeshDatabase(
        vertices=verts, faces=model.get_triangular_faces().numpy().astype(np.int32),
        weights=weights, joints=joints, joint_names=names, joint_parents=joint_parents,
        description=f"{num_bodies} adult bodies sampled from anny (seed {seed}, "
                    f"{n_wide} with uniform phenotypes)")
