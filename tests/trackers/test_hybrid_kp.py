"""The two-cue hybrid (``hybrid_kp``, mocap/trackers/keypoint_cue.py): keypoint weight 0 is the
hybrid bit for bit; where the silhouettes cannot tell (a forearm folded in front of the torso)
the keypoints bring the arm back; data without detections is refused before any work."""

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.trackers.hybrid_tracker import turned
from mocap.trackers.presets import PRESETS, make_tracker
from mocap.trackers.run import frame_of, track_sequence

FAST = {"local": {"iterations": 3}, "apf": {"particles": 10, "layers": 3}}
ARM = ("l_elbow", "l_wrist")


def keypoint_walk(body, frames: int):
    """A small walk (6 views, 200x150) with silhouettes and labelled 2D detections: 1 px noise,
    10 % false positives, 90 % detected."""
    rig = ring_rig(6, 3.5, 1.5, 200, 150, fov_deg=45, look_at=(0, 0, 0.9))
    return make_synthetic(body, rig, motion="walk", frames=frames, fps=25, seed=0, images=False,
                          detections={"enabled": True, "labelled": True, "occlusion": False,
                                      "noise_px": 1.0, "false_positive_rate": 0.1, "detection_rate": 0.9})


@pytest.fixture(scope="module")
def seq(body):
    return keypoint_walk(body, 5)


def folded_arm(body, chi):
    """The pose with the left forearm folded across the chest: every vertex of the arm stays
    inside the body's silhouette in most views, so E_S hardly tells."""
    out = np.array(chi, np.float64)
    out[body.dof_index("l_elbow_flex")] = body.limits[body.dof_index("l_elbow_flex")].max() * 0.9
    out[body.dof_index("l_shoulder_rot")] += 0.6
    return np.clip(out, body.limits[:, 0], body.limits[:, 1])


def arm_error_mm(body, seq, estimates, frames) -> float:
    idx = [body.joint_names.index(j) for j in ARM]
    errs = []
    for f in frames:
        est = estimates[f]
        got = body.shaped(est.alpha).joints(est.chi[None])[0][idx]
        want = body.shaped(seq.gt.alpha).joints(seq.gt.chi[f][None])[0][idx]
        errs.append(np.linalg.norm(got - want, axis=1).mean())
    return 1000 * float(np.mean(errs))


def test_keypoint_weight_zero_is_the_hybrid_bit_for_bit(body, seq):
    assert PRESETS["hybrid_kp"].keypoints.weight > 0
    start = folded_arm(body, seq.gt.chi[0])
    runs = []
    # both local steps hold angles at their limits (active_limits); the hybrid's repair has the stuck
    # chains' wide search and the arms' patrol, hybrid_kp's not, and hybrid_kp has its own (widened)
    # limits: matched
    for name, extra in (("hybrid", {"apf": {**FAST["apf"], "stuck_frames": 0, "patrol": 0}}),
                        ("hybrid_kp", {"keypoints": {"weight": 0.0}, "joint_limits": ""})):
        t = make_tracker(name, body=body, rig=seq.rig, rng=np.random.default_rng(3), **{**FAST, **extra})
        chi, alpha, report = t.refine_initial(frame_of(seq, 0), start, seq.gt.alpha)
        assert report == {} and chi is start and alpha is seq.gt.alpha
        runs.append(np.stack([e.chi for e in track_sequence(t, seq, start, seq.gt.alpha).estimates]))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0][1], runs[0][0])              # it tracked


def test_keypoints_fix_an_arm_the_silhouettes_cannot_see(body, seq):
    """Started with the left forearm folded across the chest, the hybrid keeps a wrong arm
    (the silhouettes hardly change); the two-cue hybrid's elbow and wrist error over the
    following frames is at most half of it and below 40 mm."""
    start = folded_arm(body, seq.gt.chi[0])
    errs = {}
    for name in ("hybrid", "hybrid_kp"):            # the preset's search budget (25 x 10)
        t = make_tracker(name, body=body, rig=seq.rig, rng=np.random.default_rng(3), local=FAST["local"])
        errs[name] = arm_error_mm(body, seq, track_sequence(t, seq, start, seq.gt.alpha).estimates,
                                  range(1, seq.num_frames))
    assert errs["hybrid_kp"] < 0.5 * errs["hybrid"] and errs["hybrid_kp"] < 40, errs


def test_the_initialisation_refinement_fixes_the_arm_with_the_cue_only(body, seq):
    """refine_initial (what init.mode=tracker runs after the silhouette initialisation): with
    the cue, the folded arm of frame 0 comes back (error at least halved); the report says the
    two-cue energy fell."""
    start = folded_arm(body, seq.gt.chi[0])
    t = make_tracker("hybrid_kp", body=body, rig=seq.rig, rng=np.random.default_rng(3), local=FAST["local"],
                     keypoints={"shape_std": 0.0})
    chi, alpha, report = t.refine_initial(frame_of(seq, 0), start, seq.gt.alpha)
    np.testing.assert_array_equal(alpha, seq.gt.alpha)             # shape_std 0: the shape kept
    r = report["keypoint_refine"]
    assert r["energy_after"] < r["energy_before"]

    class E:
        def __init__(self, c):
            self.chi, self.alpha = c, seq.gt.alpha

    assert arm_error_mm(body, seq, [E(chi)], [0]) < 0.5 * arm_error_mm(body, seq, [E(start)], [0])


def test_data_without_detections_is_refused_before_any_work(body, seq):
    no_det = make_synthetic(body, seq.rig, motion="walk", frames=2, fps=25, seed=0, images=False)
    t = make_tracker("hybrid_kp", body=body, rig=seq.rig, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"hybrid_kp uses 2D keypoint detections .* has none"):
        t.check_sequence(no_det)
    make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(0)).check_sequence(no_det)


def test_turned_keeps_the_pelvis_and_faces_the_other_way(body, seq):
    shaped = body.shaped(seq.gt.alpha)
    chi = seq.gt.chi[2].astype(np.float64)
    back = turned(shaped, chi)
    a, b = (shaped.joints(c[None])[0].astype(np.float64) for c in (chi, back))
    np.testing.assert_allclose(b[0], a[0], atol=1e-5)                       # pelvis in place
    np.testing.assert_allclose(b[1:, :2] - b[0, :2], -(a[1:, :2] - a[0, :2]), atol=1e-5)
    np.testing.assert_allclose(b[:, 2], a[:, 2], atol=1e-5)                 # heights kept
    np.testing.assert_allclose(turned(shaped, back), chi, atol=1e-9)


def test_the_keypoint_shape_fit_brings_the_bone_lengths_back(body, seq):
    """Started from the mean shape (a silhouette initialisation that got the build wrong), the
    start-up's keypoint shape fit (keypoints.shape_std > 0) moves the skeleton's bone lengths
    at least halfway to the true body's; the report says so."""
    from mocap.body.bone_lengths import skeleton_length_model

    bones, _ = skeleton_length_model(body)

    def bone_error(alpha) -> float:
        _, joints = body.rest(np.stack([alpha, seq.gt.alpha]))
        got, want = bones.lengths(np.asarray(joints, np.float64))
        return float(np.abs(got - want).mean())

    mean = np.zeros(body.num_shape)
    assert bone_error(mean) > 0.005                              # the truth is not the mean body
    t = make_tracker("hybrid_kp", body=body, rig=seq.rig, rng=np.random.default_rng(3), local=FAST["local"],
                     apf=FAST["apf"], keypoints={"shape_std": 3.0})
    _, alpha, report = t.refine_initial(frame_of(seq, 0), seq.gt.chi[0], mean)
    assert bone_error(alpha) < 0.5 * bone_error(mean), (bone_error(alpha), bone_error(mean))
    assert report["keypoint_shape"]["triangulated"] >= 10 and report["keypoint_shape"]["alpha_change"] > 0
    np.testing.assert_array_equal(t.shaped.alpha, alpha)          # the tracker goes on with it
