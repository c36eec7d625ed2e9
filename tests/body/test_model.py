import numpy as np
import pytest
import trimesh

from mocap.body import BodyModelFileError, load_body_model, load_body_model_data
from mocap.body.model_file import default_model_path

from ..conftest import body_config


def test_zero_pose_returns_rest_mesh_exactly(body64):
    sb = body64.shaped(np.linspace(-1, 1, body64.num_shape))
    out = sb.pose(body64.zero_pose(1))
    np.testing.assert_allclose(out.vertices[0], sb.rest_vertices, rtol=0, atol=1e-14)
    np.testing.assert_allclose(out.joints[0], sb.rest_joints, rtol=0, atol=1e-14)


def test_rotating_one_joint_moves_only_its_vertices_and_descendants(body64):
    sb = body64.shaped()
    chi = body64.zero_pose(1)
    chi[0, body64.dof_index("l_elbow_flex")] = 1.0
    moved = np.linalg.norm(sb.pose(chi).vertices[0] - sb.rest_vertices, axis=1) > 1e-9
    elbow, wrist = body64.joint_index("l_elbow"), body64.joint_index("l_wrist")
    influenced = body64.weights[:, [elbow, wrist]].sum(axis=1) > 0
    np.testing.assert_array_equal(moved, influenced)
    assert moved.sum() > 100


def test_joints_follow_forward_kinematics(body64):
    sb = body64.shaped()
    chi = body64.zero_pose(1)
    chi[0, body64.dof_index("l_elbow_flex")] = np.pi / 2
    J = sb.pose(chi).joints[0]
    e, w, s = (body64.joint_index(n) for n in ("l_elbow", "l_wrist", "l_shoulder"))
    rest = sb.rest_joints
    np.testing.assert_allclose(J[[e, s]], rest[[e, s]], atol=1e-12)        # parents stay
    fore_rest, fore = rest[w] - rest[e], J[w] - J[e]
    np.testing.assert_allclose(np.linalg.norm(fore), np.linalg.norm(fore_rest), rtol=1e-12)
    axis = sb.axes[body64.dof_index("l_elbow_flex") - 6]
    # a quarter turn about the hinge axis: the forearm's component across the axis turns 90 deg
    perp = lambda v: v - axis * (v @ axis)  # noqa: E731
    assert abs(perp(fore) @ perp(fore_rest)) < 1e-9
    assert fore[2] > fore_rest[2] + 0.15                                   # the hand comes up


def test_global_twist_moves_the_whole_body_rigidly(body64):
    sb = body64.shaped()
    chi = body64.zero_pose(1)
    chi[0, :3] = [0.5, -0.2, 0.1]
    out = sb.pose(chi)
    shift = np.broadcast_to([0.5, -0.2, 0.1], sb.rest_vertices.shape)
    np.testing.assert_allclose(out.vertices[0] - sb.rest_vertices, shift, atol=1e-12)


def test_batch_equals_single_evaluations_and_per_particle_shapes(body64):
    rng = np.random.default_rng(0)
    chi = rng.normal(0, 0.4, size=(5, body64.num_dofs))
    sb = body64.shaped()
    batch = sb.pose(chi)
    for p in range(5):
        single = sb.pose(chi[p])
        np.testing.assert_allclose(batch.vertices[p], single.vertices[0], atol=1e-12)
        np.testing.assert_allclose(batch.joints[p], single.joints[0], atol=1e-12)
    alpha = rng.normal(size=(5, body64.num_shape))
    per = body64.pose(chi, alpha)
    for p in range(5):
        np.testing.assert_allclose(per.vertices[p], body64.shaped(alpha[p]).pose(chi[p]).vertices[0],
                                   atol=1e-10)


def test_float32_and_float64_agree(body, body64):
    chi = np.random.default_rng(2).normal(0, 0.5, size=(8, body.num_dofs))
    v32 = body.shaped().pose(chi).vertices
    v64 = body64.shaped().pose(chi).vertices
    assert v32.dtype == np.float32 and v64.dtype == np.float64
    np.testing.assert_allclose(v32, v64, atol=2e-5)


@pytest.mark.parametrize("k", [0, 1, 2])
@pytest.mark.parametrize("s", [-3.0, 3.0])
def test_three_sigma_bodies_are_plausible_and_watertight(body64, k, s):
    alpha = np.zeros(body64.num_shape)
    alpha[k] = s
    verts, joints = body64.rest(alpha)
    stature = verts[:, 2].max() - verts[:, 2].min()
    assert 1.35 < stature < 2.05
    mesh = trimesh.Trimesh(verts, body64.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0.03
    # joints stay inside the body's bounding box
    assert np.all(joints.min(0) > verts.min(0)) and np.all(joints.max(0) < verts.max(0))


def test_shipped_model_meets_its_build_figures():
    info = load_body_model_data().info
    assert info["components"] == 20 and info["watertight"]
    assert 4000 <= info["vertices"] <= 7000
    assert info["heldout_vertex_error_mm"]["mean"] <= 2.0
    assert info["heldout_joint_from_alpha_error_mm"]["mean"] <= 5.0


def test_part_labels_cover_every_joint_with_dofs(body):
    labels = set(np.unique(body.part_labels))
    for j in set(body.dof_joint):
        assert j in labels


def test_fuller_body_has_more_dofs_and_poses(body_full):
    assert body_full.num_dofs == 36
    chi = body_full.zero_pose(2)
    chi[:, body_full.dof_index("neck_rot")] = 0.5
    out = body_full.shaped().pose(chi)
    assert np.isfinite(out.vertices).all()


# -- bad input -----------------------------------------------------------------------------

def test_wrong_pose_shape_names_the_problem(body):
    with pytest.raises(ValueError, match=r"pose chi must have shape \(22,\) or \(P, 22\)"):
        body.shaped().pose(np.zeros((3, 21)))


def test_nan_pose_is_rejected(body):
    chi = body.zero_pose(2)
    chi[1, 7] = np.nan
    with pytest.raises(ValueError, match="pose chi contains NaN"):
        body.shaped().pose(chi)


def test_wrong_or_nan_shape_is_rejected(body):
    with pytest.raises(ValueError, match=r"shape alpha must have shape \(20,\)"):
        body.shaped(np.zeros(19))
    with pytest.raises(ValueError, match="shape alpha contains NaN"):
        body.rest(np.full(20, np.nan))


def test_missing_model_file_names_the_path(tmp_path):
    with pytest.raises(BodyModelFileError, match="not found"):
        load_body_model_data(tmp_path / "nope.npz")


def test_wrong_format_model_file_is_rejected(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"this is not a zip file")
    with pytest.raises(BodyModelFileError, match="not a readable .npz"):
        load_body_model_data(bad)
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(3))
    with pytest.raises(BodyModelFileError, match="format is ''"):
        load_body_model_data(other)


def test_model_file_with_missing_or_broken_field_is_rejected(tmp_path):
    with np.load(default_model_path()) as z:
        arrays = {k: z[k] for k in z.files}
    p = tmp_path / "m.npz"
    np.savez(p, **{k: v for k, v in arrays.items() if k != "weights"})
    with pytest.raises(BodyModelFileError, match="missing field.*weights"):
        load_body_model_data(p)
    arrays["components"] = arrays["components"][:, :-1]
    np.savez(p, **arrays)
    with pytest.raises(BodyModelFileError, match="components has shape"):
        load_body_model_data(p)


def test_dof_config_errors_name_the_dof():
    dofs = body_config("paper22")["dofs"]
    bad = [dict(dofs[0], joint="l_knuckle")]
    with pytest.raises(ValueError, match="unknown joint 'l_knuckle'"):
        load_body_model(bad)
    with pytest.raises(ValueError, match="missing field 'limits_deg'"):
        load_body_model([{k: v for k, v in dofs[0].items() if k != "limits_deg"}])
    with pytest.raises(ValueError, match="min < max"):
        load_body_model([dict(dofs[0], limits_deg=[10, -10])])
