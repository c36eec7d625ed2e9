"""Rest-joint corrections (a person's skeleton inside the shape's outline): the map from rest
joints to posed landmarks is affine for fixed angles and axes, the corrections leave the rest mesh
alone, a known skeleton is recovered from exact keypoints, and no corrections change nothing."""

import numpy as np
import pytest

from mocap.body.catalogue import make_landmark_set, probe_poses
from mocap.body.dofs import resolve_axes
from mocap.body.skeleton import (
    fit_joint_offsets,
    frames_by_body,
    joint_offsets_of,
    marked_joints,
    offset_map,
    posed_landmarks,
)


def _poses(body, count, seed=0):
    rng = np.random.default_rng(seed)
    chis = probe_poses(body, count)
    chis[:, :6] = rng.normal(scale=0.3, size=(count, 6))
    return chis


def test_posed_landmarks_are_affine_in_the_rest_joints(body64):
    """x -> R x + (I - R) q per twist: with the angles and axes held, the landmarks of rest joints
    J + delta are A vec(delta) + b (the map built from two evaluations) for any delta."""
    rng = np.random.default_rng(1)
    lms = make_landmark_set(body64, "default")
    alpha = rng.normal(size=body64.num_shape)
    chis = _poses(body64, 4)
    _, J = body64.rest(alpha)
    axes = resolve_axes(body64.dofs, body64.joint_names, J)
    A, b = offset_map(body64, lms, alpha, chis, J, axes)
    for scale in (0.001, 0.05, 0.3):
        d = rng.normal(scale=scale, size=J.shape)
        x = posed_landmarks(body64, lms, alpha, chis, np.broadcast_to(J + d, (len(chis),) + J.shape), axes)
        np.testing.assert_allclose(x, A @ d.ravel() + b, atol=1e-9, rtol=0)


def test_offsets_move_the_joints_and_not_the_rest_mesh(body64):
    """At the zero pose the surface is the shape's, vertex for vertex, whatever the corrections;
    the joints are the shape's plus the corrections; posed, the joints' rigid frames use them."""
    rng = np.random.default_rng(2)
    alpha = rng.normal(size=body64.num_shape)
    d = rng.normal(scale=0.03, size=(body64.num_joints, 3))
    plain, moved = body64.shaped(alpha), body64.shaped(alpha, joint_offsets=d)
    zero = body64.zero_pose()
    np.testing.assert_array_equal(moved.pose(zero).vertices, plain.pose(zero).vertices)
    np.testing.assert_allclose(moved.pose(zero).joints[0], plain.rest_joints + d, atol=1e-12)
    np.testing.assert_allclose(moved.rest_joints - plain.rest_joints, d, atol=1e-12)
    chi = _poses(body64, 1)[0]
    assert np.abs(moved.pose(chi).vertices - plain.pose(chi).vertices).max() > 1e-3
    np.testing.assert_array_equal(body64.pose(chi, alpha, d).joints, moved.pose(chi).joints)


def test_no_offsets_is_bit_identical(body):
    """joint_offsets None (and zeros) give the shape's own body, bit for bit, in float32."""
    rng = np.random.default_rng(3)
    alpha = rng.normal(size=body.num_shape)
    chis = _poses(body, 3).astype(np.float32)
    a, b, c = body.shaped(alpha), body.shaped(alpha, None), body.shaped(alpha, np.zeros((body.num_joints, 3)))
    assert b.joint_offsets is None
    for s in (b, c):
        np.testing.assert_array_equal(s.rest_joints, a.rest_joints)
        np.testing.assert_array_equal(s.axes, a.axes)
        out, ref = s.pose(chis), a.pose(chis)
        np.testing.assert_array_equal(out.vertices, ref.vertices)
        np.testing.assert_array_equal(out.joints, ref.joints)


def test_a_shaped_body_knows_the_shape_and_skeleton_it_is_for(body):
    """``ShapedBody.is_for``: the same shape and corrections (None with None, equal arrays), to the
    bit; another shape, corrections where there were none or other corrections: not."""
    alpha = np.random.default_rng(4).normal(size=body.num_shape)
    d = np.zeros((body.num_joints, 3))
    d[5] = [0.0, 0.01, 0.0]
    plain, moved = body.shaped(alpha), body.shaped(alpha, d)
    assert plain.is_for(alpha) and plain.is_for(alpha.copy(), None)
    assert moved.is_for(alpha, d.copy())
    other = alpha.copy()
    other[0] += 1e-9
    assert not plain.is_for(other) and not moved.is_for(other, d)
    assert not plain.is_for(alpha, d) and not moved.is_for(alpha) and not moved.is_for(alpha, 2 * d)


def test_frames_are_grouped_by_the_body_they_are_posed_on():
    """One group per distinct (shape, corrections), corrections None where all zero; a shape or
    corrections for every frame; a per-frame count other than the frames' refused."""
    a, b = np.zeros(3), np.ones(3)
    d = np.zeros((4, 2, 3))
    d[2:, 1] = 0.01                      # the skeleton fitted from frame 2 on
    groups = frames_by_body(np.stack([a, a, a, b]), d, 4)
    got = sorted((list(sel), tuple(alpha), None if o is None else o[1, 0] + o[1, 1])
                 for sel, alpha, o in groups)
    assert got == [([0, 1], (0, 0, 0), None), ([2], (0, 0, 0), 0.02), ([3], (1, 1, 1), 0.02)]
    (sel, alpha, o), = frames_by_body(a, None, 3)
    assert list(sel) == [0, 1, 2] and o is None and alpha.dtype == np.float64
    (sel, _, o), = frames_by_body(a, d[3], 2)
    assert list(sel) == [0, 1] and np.array_equal(o, d[3])
    with pytest.raises(ValueError, match="2 shapes for 3 poses"):
        frames_by_body(np.stack([a, b]), None, 3)
    with pytest.raises(ValueError, match="4 joint offsets for 3 poses"):
        frames_by_body(a, d, 3)


def test_offsets_are_checked_before_any_work(body):
    with pytest.raises(ValueError, match=r"joint_offsets must have shape \(19, 3\)"):
        body.shaped(None, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="joint_offsets contains NaN"):
        body.shaped(None, np.full((body.num_joints, 3), np.nan))


def test_a_known_skeleton_is_recovered_from_exact_keypoints(body64):
    """A body whose true skeleton is the shape's moved by a known delta (the joints a keypoint
    sits on, up to 4 cm), seen in 12 poses through exact keypoints: the fit (axes resolved from
    the corrected joints, as the body poses) finds delta within 1 mm; the joints no landmark
    sits on stay at 0."""
    rng = np.random.default_rng(4)
    lms = make_landmark_set(body64, "default")
    alpha = rng.normal(size=body64.num_shape)
    chis = _poses(body64, 12)
    marked = sorted({body64.joint_index(lm.at) for lm in lms.landmarks if lm.at is not None})
    d = np.zeros((body64.num_joints, 3))
    d[marked] = rng.uniform(-0.04, 0.04, size=(len(marked), 3))
    truth = body64.shaped(alpha, d)
    y = lms.positions(truth, chis)
    fit = fit_joint_offsets(body64, lms, alpha, chis, y, std=0.05, noise=0.002)
    assert np.abs(fit.offsets[marked] - d[marked]).max() < 1e-3
    assert marked_joints(body64, lms).tolist() == marked
    assert not np.delete(fit.offsets, marked, axis=0).any()
    assert fit.report["rms_after_mm"] < 0.5 < fit.report["rms_before_mm"]
    # a third of the keypoints missing and one frame's wrist 30 cm off: still within 1 mm
    y2 = y.copy()
    y2[rng.random(y2.shape[:2]) < 0.3] = np.nan
    y2[5, lms.names.index("l_wrist")] += [0.3, 0.0, 0.0]
    fit2 = fit_joint_offsets(body64, lms, alpha, chis, y2, std=0.05, noise=0.002)
    assert np.abs(fit2.offsets[marked] - d[marked]).max() < 1e-3


def test_bad_keypoints_are_refused(body64):
    lms = make_landmark_set(body64, "default")
    with pytest.raises(ValueError, match=r"measured landmarks have shape \(2, 3, 3\)"):
        fit_joint_offsets(body64, lms, np.zeros(body64.num_shape), _poses(body64, 2), np.zeros((2, 3, 3)),
                          std=0.03)


def test_joint_offsets_of_estimates():
    class E:
        def __init__(self, d=None):
            self.joint_offsets = d

    assert joint_offsets_of([E(), E()], 2) is None
    out = joint_offsets_of([E(), E(np.ones((2, 3)))], 2)
    np.testing.assert_array_equal(out, [np.zeros((2, 3)), np.ones((2, 3))])


def test_metrics_pose_each_frame_with_its_offsets(body):
    """per_shape groups frames by shape and corrections: a frame's points are those of its own
    corrected body; with none (None) the call is the one before corrections existed."""
    from mocap.eval.estimates import per_shape

    rng = np.random.default_rng(6)
    alpha = rng.normal(size=body.num_shape)
    chis = _poses(body, 4).astype(np.float32)
    d = rng.normal(scale=0.02, size=(body.num_joints, 3))
    offsets = np.stack([np.zeros_like(d), d, d, np.zeros_like(d)])
    out = per_shape(body, alpha, chis, lambda s, c: s.joints(c), offsets)
    np.testing.assert_array_equal(out[[1, 2]], body.shaped(alpha, d).joints(chis[[1, 2]]))
    np.testing.assert_array_equal(out[[0, 3]], body.shaped(alpha).joints(chis[[0, 3]]))
    np.testing.assert_array_equal(per_shape(body, alpha, chis, lambda s, c: s.joints(c)),
                                  body.shaped(alpha).joints(chis))
