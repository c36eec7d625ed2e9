"""Ground truth matched by joint name: permuted orders, foreign skeletons, PCP, clear errors."""

import dataclasses

import cv2
import numpy as np
import pytest

from mocap.body.skeletons import SKELETONS, JointNameError
from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.data.sequence_io import load_sequence, write_sequence
from mocap.eval.by_name import NameScorer, score_by_name
from mocap.eval.metrics import EVAL_JOINTS, joint_errors, mpjpe_summary
from mocap.eval.run_metrics import run_metrics
from mocap.trackers.base import Estimate


@pytest.fixture(scope="module")
def seq(body):
    rig = ring_rig(3, 3.5, 1.5, 96, 72, fov_deg=50)
    return make_synthetic(body, rig, motion="walk", frames=4, fps=25, seed=2)


def _estimates(body, seq, offset=0.02):
    rng = np.random.default_rng(0)
    chis = seq.gt.chi + offset * rng.standard_normal(seq.gt.chi.shape)
    return [Estimate(c, seq.gt.alpha) for c in chis]


def test_permuted_ground_truth_scores_like_the_original(body, seq):
    ests = _estimates(body, seq)
    base = run_metrics(body, seq, ests, [0.0] * 4)
    # the old path, joints in the body's order, gives the same figure
    chis = np.stack([e.chi for e in ests])
    old = mpjpe_summary(joint_errors(body.shaped(seq.gt.alpha).joints(chis), seq.gt.joints, body.joint_names))
    assert base["mpjpe_mm"] == pytest.approx(old["mpjpe_mm"], rel=1e-9)
    perm = np.random.default_rng(1).permutation(body.num_joints)
    gt = dataclasses.replace(seq.gt, joints=seq.gt.joints[:, perm],
                             joint_names=tuple(body.joint_names[i] for i in perm))
    permuted = run_metrics(body, dataclasses.replace(seq, gt=gt), ests, [0.0] * 4)
    assert permuted["mpjpe_mm"] == pytest.approx(base["mpjpe_mm"], rel=1e-9)
    assert permuted["per_joint_mm"] == pytest.approx(base["per_joint_mm"], rel=1e-9)
    truth = seq.gt.joints[:, perm]                              # the true pose scores ~0, not 603 mm
    exact = [Estimate(c, seq.gt.alpha) for c in seq.gt.chi]
    assert run_metrics(body, dataclasses.replace(seq, gt=dataclasses.replace(gt, joints=truth)),
                       exact, [0.0] * 4)["mpjpe_mm"] < 0.01


def test_bad_joint_names_are_named(body, seq):
    pts = {n: seq.gt.joints[:, i] for i, n in enumerate(body.joint_names)}
    names = list(body.joint_names)
    renamed = ["lknee" if n == "l_knee" else n for n in names]
    with pytest.raises(JointNameError, match="unknown joints lknee"):
        score_by_name(pts, renamed, seq.gt.joints, required=EVAL_JOINTS)
    with pytest.raises(JointNameError, match="missing joints l_wrist"):
        keep = [i for i, n in enumerate(names) if n != "l_wrist"]
        score_by_name(pts, [names[i] for i in keep], seq.gt.joints[:, keep], required=EVAL_JOINTS)
    coco = list(SKELETONS["coco17"])
    with pytest.raises(JointNameError, match=r"unknown joints spine.*missing joints nose"):
        score_by_name(pts, ["spine", *coco[1:]], np.zeros((4, 17, 3)), skeleton="coco17")
    with pytest.raises(JointNameError, match="unknown skeleton 'h36m'"):
        score_by_name(pts, coco, np.zeros((4, 17, 3)), skeleton="h36m")


def test_chi_of_another_body_is_a_clear_error(body, seq):
    gt = dataclasses.replace(seq.gt, chi=np.zeros((4, 40)))
    with pytest.raises(ValueError, match="ground-truth chi is \\(4, 40\\).*22 DOFs"):
        NameScorer(body, gt)


def test_pcp_and_root_aligned_error_on_a_hand_made_case():
    """Shelf skeleton, one frame. Upper arm 0.30 m long, lower arm 0.25 m, legs 0.40 m. The
    estimate shifts the left shoulder and elbow by 0.10 m (upper arm correct: mean 0.10 <= 0.15;
    lower arm: elbow 0.10, wrist 0.30 -> mean 0.20 > 0.125, wrong), everything else exact."""
    names = list(SKELETONS["shelf14"])
    gt = {n: np.zeros(3) for n in names}
    gt.update({"Left-Shoulder": np.array([0.2, 0, 1.4]), "Left-Elbow": np.array([0.5, 0, 1.4]),
               "Left-Wrist": np.array([0.75, 0, 1.4]), "Right-Shoulder": np.array([-0.2, 0, 1.4]),
               "Right-Elbow": np.array([-0.5, 0, 1.4]), "Right-Wrist": np.array([-0.75, 0, 1.4]),
               "Left-Hip": np.array([0.1, 0, 0.9]), "Left-Knee": np.array([0.1, 0, 0.5]),
               "Left-Ankle": np.array([0.1, 0, 0.1]), "Right-Hip": np.array([-0.1, 0, 0.9]),
               "Right-Knee": np.array([-0.1, 0, 0.5]), "Right-Ankle": np.array([-0.1, 0, 0.1]),
               "Bottom-Head": np.array([0, 0, 1.5]), "Top-Head": np.array([0, 0, 1.75])})
    ours = {SKELETONS["shelf14"][n]: gt[n][None].copy() for n in names}
    ours["l_shoulder"] += [0, 0.1, 0]
    ours["l_elbow"] += [0, 0.1, 0]
    ours["l_wrist"] += [0, 0.3, 0]
    gt_arr = np.stack([gt[n] for n in names])[None]
    r = score_by_name(ours, names, gt_arr, skeleton="shelf14")
    assert r["pcp_per_limb"]["l_upper_arm"] == 1.0 and r["pcp_per_limb"]["l_lower_arm"] == 0.0
    # limbs: head, upper/lower arms, upper/lower legs = 9 (no torso: Shelf has no pelvis joint)
    assert set(r["pcp_per_limb"]) == {"head", "l_upper_arm", "r_upper_arm", "l_lower_arm", "r_lower_arm",
                                      "l_upper_leg", "r_upper_leg", "l_lower_leg", "r_lower_leg"}
    assert r["pcp"] == pytest.approx(8 / 9)
    assert r["mpjpe_mm"] == pytest.approx((100 + 100 + 300) / 14)
    # root = mid-hips (unchanged), so root alignment changes nothing here
    assert r["mpjpe_root_aligned_mm"] == pytest.approx(r["mpjpe_mm"])
    # an invalid joint is left out: mark the wrist invalid -> lower arm not counted
    valid = np.ones((1, 14), bool)
    valid[0, names.index("Left-Wrist")] = False
    r2 = score_by_name(ours, names, gt_arr, valid=valid, skeleton="shelf14")
    assert "l_lower_arm" not in r2["pcp_per_limb"] and r2["pcp"] == 1.0
    assert r2["mpjpe_mm"] == pytest.approx(200 / 13)


def test_coco_ground_truth_leaves_out_unmodelled_points(body, seq):
    table = SKELETONS["coco17"]
    names = list(table)
    gt = np.stack([seq.gt.joints[:, body.joint_index(table[n])] if table[n] else
                   np.full((4, 3), np.nan) for n in names], axis=1)
    pts = {n: seq.gt.joints[:, i] for i, n in enumerate(body.joint_names)}
    r = score_by_name(pts, names, gt, skeleton="coco17")
    assert r["mpjpe_mm"] == pytest.approx(0.0, abs=1e-9) and r["pcp"] == 1.0
    assert r["unscored"] == ["nose", "left_eye", "right_eye", "left_ear", "right_ear"]


def test_masks_load_the_same_from_01_0255_and_bool_pngs(body, seq, tmp_path):
    from PIL import Image

    folder = write_sequence(dataclasses.replace(seq, images=None), tmp_path / "seq")
    ref = load_sequence(folder)
    files = sorted((folder / "masks").rglob("*.png"))
    for k, path in enumerate(files):
        m = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE) > 127
        if k % 3 == 0:
            cv2.imwrite(str(path), m.astype(np.uint8))                     # 0/1
        elif k % 3 == 1:
            Image.fromarray(m).save(path)                                   # 1-bit PNG
    np.testing.assert_array_equal(load_sequence(folder).masks, ref.masks)
    assert ref.masks.any(axis=(0, 2, 3)).all()
    view = ref.rig.names[1]
    for path in (folder / "masks" / view).glob("*.png"):
        cv2.imwrite(str(path), np.zeros(ref.masks.shape[2:], np.uint8))
    with pytest.warns(UserWarning, match=f"view\\(s\\) {view} are empty in every frame"):
        load_sequence(folder)


def test_name_only_ground_truth_round_trips(body, seq, tmp_path):
    g = seq.gt
    gt = dataclasses.replace(g, alpha=None, chi=None, markers=None, dof_names=(), marker_names=(),
                             joint_valid=np.ones(g.joints.shape[:2], bool))
    back = load_sequence(write_sequence(dataclasses.replace(seq, gt=gt, images=None), tmp_path / "s"))
    assert back.gt.chi is None and back.gt.joint_valid.all() and back.num_frames == 4
    ests = _estimates(body, seq)
    assert run_metrics(body, back, ests, [0.0] * 4)["mpjpe_mm"] == pytest.approx(
        run_metrics(body, seq, ests, [0.0] * 4)["mpjpe_mm"], rel=1e-6)


def test_converter_from_named_joint_files(body, seq, tmp_path):
    """Per-frame CSVs in millimetres, a joint missing in one frame, into a sequence folder;
    the loaded ground truth scores the true pose at 0 with the missing entry left out."""
    from mocap.data.named_joints import add_ground_truth, read_named_joints

    joints_dir = tmp_path / "joints"
    joints_dir.mkdir()
    names = list(body.joint_names)[::-1]                     # another order
    for f in range(4):
        rows = ["joint,x,y,z"]
        for n in names:
            x, y, z = 1e3 * seq.gt.joints[f, body.joint_index(n)]
            rows.append(f"{n},,," if (f == 2 and n == "l_wrist") else f"{n},{x},{y},{z}")
        (joints_dir / f"{f:04d}.csv").write_text("\n".join(rows) + "\n")
    got_names, joints, valid = read_named_joints(joints_dir, scale=1e-3)
    assert list(got_names) == names and joints.shape == (4, 19, 3)
    assert (~valid).sum() == 1 and not valid[2, names.index("l_wrist")]
    folder = write_sequence(dataclasses.replace(seq, images=None, gt=None), tmp_path / "s")
    add_ground_truth(folder, got_names, joints, valid)
    back = load_sequence(folder)
    exact = [Estimate(c, seq.gt.alpha) for c in seq.gt.chi]
    m = run_metrics(body, back, exact, [0.0] * 4)
    assert m["mpjpe_mm"] < 0.01 and m["per_joint_mm"]["l_wrist"] < 0.01
    with pytest.raises(FileExistsError):
        add_ground_truth(folder, got_names, joints, valid)
