"""Keypoint-to-landmark offsets (mocap/trackers/markers/offsets.py)."""

from pathlib import Path

import numpy as np
import pytest

from mocap.body.twists import se3_exp
from mocap.trackers.markers.offsets import local_residuals, offset_significance, robust_offsets
from mocap.trackers.tracker_settings import OffsetLearning

DEV = Path(__file__).resolve().parents[2] / "data" / "real_motion" / "dev"


def test_residuals_in_the_joint_frame_recover_a_body_fixed_offset():
    rng = np.random.default_rng(0)
    L, T = 5, 6
    rest = rng.normal(0, 0.3, (L, 3))
    offset = rng.normal(0, 0.03, (L, 3))
    samples = []
    for _ in range(T):
        G = se3_exp(rng.normal(0, 1.0, (L, 6)))                     # each landmark's joint, posed
        X = np.einsum("lij,lj->li", G[:, :3, :3], rest + offset) + G[:, :3, 3]
        samples.append(local_residuals(G, X, rest))
    np.testing.assert_allclose(np.stack(samples), np.broadcast_to(offset, (T, L, 3)), atol=1e-12)


def test_robust_offsets_take_the_median_clip_and_need_samples():
    o = np.array([[0.02, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.01]])
    samples = np.repeat(o[None], 5, axis=0).copy()
    samples[0, 0] = [1.0, 1.0, 1.0]                                 # an outlier frame
    samples[:3, 2] = np.nan                                         # landmark 2 seen in 2 frames only
    out = robust_offsets(samples, OffsetLearning(frames=5, max_norm=0.08, min_samples=3))
    np.testing.assert_allclose(out[0], o[0], atol=1e-12)
    np.testing.assert_allclose(out[1], [0.0, 0.08, 0.0], atol=1e-12)   # clipped to 8 cm
    np.testing.assert_array_equal(out[2], 0.0)


def test_significance_keeps_a_true_3cm_offset_and_drops_pure_noise():
    # 30 frames of 1 cm per-axis noise: landmark 0 has a true (3, 0, 0) cm offset, landmark 1 none
    rng = np.random.default_rng(1)
    T = 30
    samples = rng.normal(0.0, 0.01, (T, 2, 3))
    samples[:, 0] += [0.03, 0.0, 0.0]
    z = offset_significance(samples)
    # the median's standard error is 1.2533 x 1 cm / sqrt(30) = 2.3 mm: 3 cm is ~13 of them
    assert 9.0 < z[0] < 17.0
    assert z[1] < 4.0                                               # noise: ~sqrt(3)
    out = robust_offsets(samples, OffsetLearning(frames=T, significance=5.0))
    np.testing.assert_allclose(out[0], [0.03, 0.0, 0.0], atol=0.005)
    np.testing.assert_array_equal(out[1], 0.0)
    kept = robust_offsets(samples, OffsetLearning(frames=T))        # 0: every median kept
    assert np.linalg.norm(kept[1]) > 0


def test_significance_of_pure_noise_follows_a_chi_with_3_dof():
    rng = np.random.default_rng(2)
    z = offset_significance(rng.normal(0.0, 0.02, (40, 2000, 3)))
    assert abs(np.median(z) - 1.54) < 0.15                           # median of chi(3): 1.538
    assert np.mean(z > 5.0) < 0.005


def test_significance_is_zero_where_a_landmark_is_measured_in_fewer_than_two_frames():
    samples = np.full((5, 2, 3), np.nan)
    samples[0, 0] = [0.05, 0.0, 0.0]
    samples[:, 1] = [0.0, 0.02, 0.0]                                # no spread: 1 um counts
    z = offset_significance(samples)
    assert z[0] == 0.0 and z[1] > 1e3


def test_offset_significance_setting_is_refused_below_zero():
    with pytest.raises(ValueError, match="significance"):
        OffsetLearning(significance=-1.0)


def test_tracker_learns_offsets_and_refines_on_synthetic_markers(body):
    from mocap.cameras import rig_from_config
    from mocap.data.generate import make_synthetic
    from mocap.eval.metrics import joint_errors
    from mocap.trackers.presets import make_tracker
    from mocap.trackers.run import track_sequence

    rig = rig_from_config("humaneva")
    det = {"enabled": True, "detection_rate": 0.9, "false_positive_rate": 0.1, "noise_px": 2.0,
           "occlusion": False}
    seq = make_synthetic(body, rig, motion="walk", frames=8, fps=25, seed=3, masks=False, detections=det)
    trk = make_tracker("marker_apf", body=body, rig=rig, rng=np.random.default_rng(0),
                       refine={"iterations": 2}, offsets={"frames": 4})
    res = track_sequence(trk, seq, seq.gt.chi[0], seq.gt.alpha)
    assert trk.offsets is not None and np.all(np.isfinite(trk.offsets))
    assert np.linalg.norm(trk.offsets, axis=1).max() < 0.03      # markers are the landmarks: ~no offset
    assert res.estimates[-1].diagnostics["refinement"]["iterations"] == 2
    chis = np.stack([e.chi for e in res.estimates])
    err = joint_errors(body.shaped(seq.gt.alpha).joints(chis), seq.gt.joints, body.joint_names)
    assert err[1:].mean() < 20.0


def _offset_run(body, offsets_mm, frames_learned, profile=None):
    """Mean landmark error (mm, frames 12..) of marker_apf started at the truth on a synthetic
    walk whose detections mark the 15 HumanEva keypoints with constant offsets ``offsets_mm``
    (mocap.data.detector_semantics, no other corruption but 1.5 px noise)."""
    from mocap.body.catalogue import make_landmark_set
    from mocap.body.skeletons import SKELETONS
    from mocap.cameras import rig_from_config
    from mocap.data.detector_semantics import DetectorSemantics, simulate
    from mocap.data.generate import make_synthetic
    from mocap.trackers.presets import make_tracker
    from mocap.trackers.run import track_sequence

    rig = rig_from_config("humaneva")
    seq = make_synthetic(body, rig, motion="walk", frames=30, fps=25, seed=5, masks=False)
    names = list(SKELETONS["humaneva15"].values())
    lms = make_landmark_set(body, names)
    truth = lms.positions(body.shaped(seq.gt.alpha), seq.gt.chi).astype(np.float64)
    s = DetectorSemantics(offsets_mm=offsets_mm, offset_jitter_mm=0.0, swap_rate=0.0, foreign_limb_rate=0.0,
                          gross_rate=0.0, false_positive_rate=0.0, detection_rate=1.0, noise_px=1.5)
    det = simulate(truth, names, rig, s, np.random.default_rng(0)).detections
    from dataclasses import replace

    trk = make_tracker("marker_apf", body=body, rig=rig, rng=np.random.default_rng(0),
                       offsets={"frames": frames_learned}, keypoint_profile=profile)
    res = track_sequence(trk, replace(seq, detections=det), seq.gt.chi[0], seq.gt.alpha)
    chis = np.stack([e.chi for e in res.estimates])
    est = make_landmark_set(body, list(trk.landmarks.names)).positions(body.shaped(seq.gt.alpha), chis)
    idx = [names.index(n) for n in trk.landmarks.names]
    return 1e3 * float(np.linalg.norm(est[12:] - truth[12:, idx], axis=-1).mean())


@pytest.mark.slow
def test_offsets_remove_a_constant_detector_bias_and_do_not_hurt_without_one(body):
    """Constant keypoint offsets (the realistic detector's, hips 5 cm up and out) bias the
    tracker; offsets learned online on top of the detector's profile (its calibrated mean
    offsets) remove most of it; learned online alone they leave the pose where it is (a pose
    change mimics offsets shared by neighbouring keypoints: the residuals they learn from are
    the pose's own); on unbiased detections learning them does not hurt."""
    from mocap.data.detector_semantics import REALISTIC_OFFSETS_MM

    biased_off = _offset_run(body, REALISTIC_OFFSETS_MM, 0)
    biased_on = _offset_run(body, REALISTIC_OFFSETS_MM, 8, profile="realistic_sim")
    assert biased_on < 0.6 * biased_off, (biased_on, biased_off)
    assert _offset_run(body, REALISTIC_OFFSETS_MM, 8) > 0.9 * biased_off
    plain_off, plain_on = (_offset_run(body, {}, n) for n in (0, 8))
    assert plain_on < plain_off + 1.0, (plain_on, plain_off)


def test_removing_a_profile_gives_back_the_joints_of_keypoints_with_its_offsets():
    """Keypoints simulated with exactly a profile's offsets, minus the profile: the joints."""
    from mocap.data.detector_semantics import DetectorSemantics, gt_keypoint_names, simulate
    from mocap.data.sequence_io import load_sequence
    from mocap.trackers.markers.offsets import PROFILES, remove_profile

    seq = load_sequence(DEV / "bye_petite_woman", images=False)
    names = gt_keypoint_names(seq.gt)
    s = DetectorSemantics(offsets_mm=PROFILES["realistic_sim"], offset_jitter_mm=0.0)
    sim = simulate(seq.gt.joints[:5], names, seq.rig, s, np.random.default_rng(0))
    for f in range(5):
        # the keypoint frames come from the keypoints themselves: exact up to their small tilt
        back = remove_profile("realistic_sim", names, sim.keypoints[f])
        assert np.abs(back - seq.gt.joints[f]).max() < 0.006
        assert np.abs(sim.keypoints[f] - seq.gt.joints[f]).max() > 0.04


def test_keypoint_profile_auto_follows_the_sequence_and_names_are_checked(body):
    from mocap.data.sources import folder_sequence
    from mocap.trackers.presets import make_tracker

    path = DEV / "walk_heavy_man"
    seq = folder_sequence(body=body, path=str(path), images=False, detections={"semantics": "realistic"})
    trk = make_tracker("marker_apf", body=body, rig=seq.rig, rng=np.random.default_rng(0))
    trk.check_sequence(seq)
    assert trk.profile == "realistic_sim"
    plain = folder_sequence(body=body, path=str(path), images=False)
    trk.check_sequence(plain)
    assert trk.profile is None
    with pytest.raises(ValueError, match="keypoint_profile"):
        make_tracker("marker_apf", body=body, rig=seq.rig, rng=np.random.default_rng(0),
                     keypoint_profile="openpose_v9")
