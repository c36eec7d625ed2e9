"""The model-building pipeline on databases with known answers (no anny needed)."""

import numpy as np
import pytest
import trimesh

from mocap.body import load_body_model_data
from mocap.body.build import pca, skeleton
from mocap.body.build.assemble import BuildSettings, build_model
from mocap.body.build.database import load_mesh_folder

rng = np.random.default_rng(0)


def test_pca_recovers_a_low_rank_database_exactly():
    mean = rng.normal(size=(40, 3))
    basis = np.linalg.qr(rng.normal(size=(120, 4)))[0].T.reshape(4, 40, 3)
    coef = rng.normal(size=(60, 4)) * np.array([5.0, 3.0, 2.0, 1.0])
    meshes = mean + np.einsum("nk,kvc->nvc", coef, basis)
    m, comps, std = pca.learn_pca(meshes, 4)
    assert np.all(np.diff(std) < 0)
    flat = comps.reshape(4, -1)
    np.testing.assert_allclose(flat @ flat.T, np.eye(4), atol=1e-10)
    alpha = pca.project(meshes, m, comps, std)
    np.testing.assert_allclose(pca.reconstruct(alpha, m, comps, std), meshes, atol=1e-10)
    np.testing.assert_allclose(alpha.std(axis=0, ddof=1), 1.0, atol=1e-10)


def test_fit_linear_and_vertex_regressor_recover_linear_joints():
    alpha = rng.normal(size=(50, 3))
    mean, basis = rng.normal(size=(5, 3)), rng.normal(size=(3, 5, 3))
    joints = mean + np.einsum("nk,kjc->njc", alpha, basis)
    m, b = skeleton.fit_linear(alpha, joints)
    np.testing.assert_allclose(m, mean, atol=1e-10)
    np.testing.assert_allclose(b, basis, atol=1e-10)


def test_nearest_owned_ancestor_and_weight_reduction():
    parents = np.array([-1, 0, 1, 1, 3])
    owner = skeleton.nearest_owned_ancestor(parents, {0: 0, 3: 1})
    np.testing.assert_array_equal(owner, [0, 0, 0, 1, 1])
    w = np.array([[0.5, 0.2, 0.1, 0.1, 0.1]])
    np.testing.assert_allclose(skeleton.reduce_weights(w, owner, 2), [[0.8, 0.2]])


@pytest.fixture(scope="module")
def mesh_folder(tmp_path_factory, body64):
    """30 bodies of the shipped model along 5 components, written as PLY files."""
    folder = tmp_path_factory.mktemp("db")
    alpha = np.zeros((30, body64.num_shape))
    alpha[:, :5] = rng.normal(size=(30, 5))
    verts, joints = body64.rest(alpha)
    for i, v in enumerate(verts):
        trimesh.Trimesh(v, body64.faces, process=False).export(folder / f"body_{i:03d}.ply")
    return folder, verts, joints


def test_build_from_a_folder_of_registered_meshes(mesh_folder, body64):
    folder, verts, joints = mesh_folder
    db = load_mesh_folder(folder)
    assert db.vertices.shape == verts.shape
    model, report = build_model(db, BuildSettings(num_components=5, heldout_fraction=0.2),
                                reference=load_body_model_data())
    assert report["heldout_vertex_error_mm"]["mean"] < 0.05      # the data are 5-dimensional
    assert report["heldout_joint_from_alpha_error_mm"]["mean"] < 5.0
    # registered to the reference topology: its skinning weights are reused
    np.testing.assert_allclose(model.weights, body64.weights, atol=1e-6)
    # rest joints of the new model reproduce the bodies' joints
    alpha = pca.project(verts, model.mean, model.components, model.stddev)
    pred = model.joints_mean + np.einsum("nk,kjc->njc", alpha, model.joints_basis)
    assert np.linalg.norm(pred - joints, axis=-1).mean() < 0.005


def test_folder_with_mixed_topologies_names_the_file(mesh_folder, tmp_path):
    folder, verts, _ = mesh_folder
    for p in sorted(folder.iterdir())[:3]:
        (tmp_path / p.name).write_bytes(p.read_bytes())
    trimesh.creation.icosphere().export(tmp_path / "zz_sphere.ply")
    with pytest.raises(ValueError, match="zz_sphere.ply: topology differs"):
        load_mesh_folder(tmp_path)
