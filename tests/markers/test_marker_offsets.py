"""Keypoint-to-landmark offsets (mocap/trackers/markers/offsets.py)."""

import numpy as np

from mocap.body.twists import se3_exp
from mocap.trackers.markers.offsets import OffsetLearning, local_residuals, robust_offsets


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
