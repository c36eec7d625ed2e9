"""Evaluation under model mismatch: offset removal, limb joints and the oracle fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from mocap.body import load_body
from mocap.data.generate import subject_shape
from mocap.data.motion import generate_motion
from mocap.eval.mismatch import LIMB_JOINTS, fit_oracle, geometric_median, heading_frames, mismatch_metrics


@pytest.fixture(scope="module")
def body():
    return load_body("paper22")


def own_joints(body, motion: str, frames: int, seed: int = 3):
    chi = generate_motion(body, motion, frames, fps=25, seed=seed, split="test", radius=1.0)
    alpha = subject_shape(body, seed, 0.8)
    return chi, alpha, body.shaped(alpha).joints(chi).astype(np.float64)


def test_geometric_median_minimises_the_sum_of_distances():
    pts = np.random.default_rng(0).normal(size=(40, 3)) * [1.0, 2.0, 0.5] + [3.0, -1.0, 0.2]
    pts[:5] += 20.0                                           # outliers pull the mean, not the median
    ref = minimize(lambda m: np.linalg.norm(pts - m, axis=1).sum(), pts.mean(axis=0),
                   method="Nelder-Mead", options={"xatol": 1e-9, "fatol": 1e-12, "maxiter": 20000}).x
    np.testing.assert_allclose(geometric_median(pts), ref, atol=1e-4)


def test_heading_frame_follows_the_hips():
    left = np.array([[0.0, 1.0, 0.9], [-1.0, 0.0, 0.9]])
    right = np.zeros((2, 3)) + [0.0, 0.0, 0.9]
    R = heading_frames(left, right)
    np.testing.assert_allclose(R[0] @ [1, 0, 0], [0, 1, 0], atol=1e-12)     # x along right->left
    np.testing.assert_allclose(R[1] @ [1, 0, 0], [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(R @ [0, 0, 1], [[0, 0, 1]] * 2, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0)


def test_a_constant_offset_that_turns_with_the_body_is_removed(body):
    _, _, J = own_joints(body, "walk", 40)                   # a walk on a circle: the heading turns
    names = list(body.joint_names)
    il, ir, it = names.index("l_hip"), names.index("r_hip"), names.index("thorax")
    R = heading_frames(J[:, il], J[:, ir])
    truth = J.copy()
    truth[:, it] += R @ np.array([0.0, -0.06, 0.04])           # a thorax defined 7 cm elsewhere
    est = {n: J[:, i] for i, n in enumerate(names)}
    m = mismatch_metrics(est, names, truth)
    assert m["raw_mm"] == pytest.approx(1e3 * np.hypot(0.06, 0.04) / len(names), rel=1e-6)
    assert m["offset_removed_mm"] < 1e-6
    assert m["offsets_mm"]["thorax"] == pytest.approx(1e3 * np.hypot(0.06, 0.04), rel=1e-6)
    assert m["limbs_mm"] == pytest.approx(0.0, abs=1e-9)       # the thorax is not a limb joint
    assert m["frames_lost"] == 0


def test_offset_removed_error_never_exceeds_the_raw_error(body):
    _, _, J = own_joints(body, "box", 30)
    rng = np.random.default_rng(1)
    noisy = J + rng.normal(0, 0.03, J.shape) + rng.normal(0, 0.05, (1, J.shape[1], 3))
    names = list(body.joint_names)
    m = mismatch_metrics({n: noisy[:, i] for i, n in enumerate(names)}, names, J)
    assert m["offset_removed_mm"] <= m["raw_mm"]
    assert m["limbs_offset_removed_mm"] <= m["limbs_mm"]
    # the limb score uses only the 10 limb joints
    err = 1e3 * np.linalg.norm(noisy - J, axis=-1)[:, [names.index(n) for n in LIMB_JOINTS]]
    assert m["limbs_mm"] == pytest.approx(err.mean(), rel=1e-9)


def test_lost_frames_are_counted():
    names = ["pelvis", "l_hip", "r_hip", "l_knee"]
    gt = np.zeros((5, 4, 3)) + [[0, 0, 1], [0.1, 0, 0.9], [-0.1, 0, 0.9], [0.1, 0, 0.5]]
    est = gt.copy()
    est[3] += [0.2, 0, 0]                                     # 200 mm on every joint in frame 3
    m = mismatch_metrics({n: est[:, i] for i, n in enumerate(names)}, names, gt)
    assert m["frames_lost"] == 1
    est[0] += [0.3, 0, 0]               # a wrong initialisation is not a lost frame (as run_metrics)
    m = mismatch_metrics({n: est[:, i] for i, n in enumerate(names)}, names, gt)
    assert m["frames_lost"] == 1


@pytest.mark.slow
@pytest.mark.parametrize("motion", ["walk", "box"])
def test_oracle_reaches_ground_truth_made_by_our_own_model(body, motion):
    chi, alpha, J = own_joints(body, motion, 20)
    fit = fit_oracle(body, body.joint_names, J)
    assert fit.metrics["raw_mm"] < 0.1
    assert fit.chi.shape == (20, body.num_dofs)
    np.testing.assert_allclose(body.shaped(fit.alpha).joints(fit.chi), J, atol=5e-4)


def humaneva_truth(body):
    """Ground truth in HumanEva's names and another order, from our own walk (8 frames): its
    pelvis, thorax and head are landmarks of ours (mid-hip, neck base, head centre); the left
    wrist is missing (garbage, flagged invalid) in frames 2-4. Returns (names, joints, valid)."""
    from mocap.body.catalogue import landmarks_with
    from mocap.body.skeletons import SKELETONS
    from mocap.eval.by_name import estimate_points

    chi, alpha, J = own_joints(body, "walk", 8)
    table = SKELETONS["humaneva15"]
    gt_names = list(table)[::-1]
    marks = landmarks_with(body, list(table.values()))
    assert {"mid_hip", "neck_base", "head_centre"} <= set(marks.names)
    pts = estimate_points(body.joint_names, J, marks.names,
                          marks.positions(body.shaped(alpha), chi).astype(np.float64))
    gt = np.stack([pts[table[n]] for n in gt_names], axis=1)
    valid = np.ones(gt.shape[:2], bool)
    valid[2:5, gt_names.index("lwri")] = False
    gt[2:5, gt_names.index("lwri")] = 100.0                   # garbage where invalid
    return gt_names, gt, valid


def test_oracle_uses_the_skeleton_mapping_and_validity(body):
    """HumanEva-named ground truth in another order, a joint missing in some frames
    (:func:`humaneva_truth`), fitted like our own joints."""
    gt_names, gt, valid = humaneva_truth(body)
    fit = fit_oracle(body, gt_names, gt, valid, "humaneva15")
    assert fit.metrics["raw_mm"] < 1.0
    assert set(fit.metrics["offsets_mm"]) == set(gt_names)


@pytest.mark.parametrize("motion", ["walk", "box"])
def test_tracked_oracle_reaches_ground_truth_made_by_our_own_model(body, motion):
    """The run metrics' solver (warm-started frame to frame, issue 38) reaches our own model's
    joints as the trust region does."""
    chi, alpha, J = own_joints(body, motion, 20)
    fit = fit_oracle(body, body.joint_names, J, method="tracked")
    assert fit.metrics["raw_mm"] < 0.1
    assert fit.chi.shape == (20, body.num_dofs)
    np.testing.assert_allclose(body.shaped(fit.alpha).joints(fit.chi), J, atol=5e-4)


def test_tracked_oracle_uses_the_skeleton_mapping_and_validity(body):
    gt_names, gt, valid = humaneva_truth(body)
    fit = fit_oracle(body, gt_names, gt, valid, "humaneva15", method="tracked")
    assert fit.metrics["raw_mm"] < 1.0
    assert set(fit.metrics["offsets_mm"]) == set(gt_names)


def test_an_unknown_oracle_method_is_refused(body):
    with pytest.raises(ValueError, match="oracle method 'fast'"):
        fit_oracle(body, body.joint_names, np.zeros((2, body.num_joints, 3)), method="fast")
