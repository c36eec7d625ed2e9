"""The marker tracker end to end on synthetic detections (the marker_apf preset)."""

import numpy as np
import pytest

from mocap.cameras import rig_from_config
from mocap.data.generate import make_synthetic
from mocap.data.sequence import Detections, Sequence
from mocap.eval.metrics import joint_errors
from mocap.trackers.base import Frame
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of, track_sequence

FRAMES = 12


def tracker(body, rig, seed=0, **overrides):
    return make_tracker("marker_apf", body=body, rig=rig, rng=np.random.default_rng(seed), **overrides)


@pytest.fixture(scope="module")
def rig():
    return rig_from_config("humaneva")


def walk(body, rig, **detections) -> Sequence:
    det = {"enabled": True, "detection_rate": 1.0, "false_positive_rate": 0.0, "noise_px": 0.0,
           "occlusion": False, **detections}
    return make_synthetic(body, rig, motion="walk", frames=FRAMES, fps=25, seed=3, masks=False,
                          detections=det)


def tracking_error(body, seq, trk) -> tuple[float, list]:
    res = track_sequence(trk, seq, seq.gt.chi[0], seq.gt.alpha)
    chis = np.stack([e.chi for e in res.estimates])
    err = joint_errors(body.shaped(seq.gt.alpha).joints(chis), seq.gt.joints, body.joint_names)
    return float(err[1:].mean()), res.estimates


@pytest.fixture(scope="module")
def clean(body, rig):
    return walk(body, rig)


@pytest.fixture(scope="module")
def clean_error(body, rig, clean):
    return tracking_error(body, clean, tracker(body, rig))[0]


def test_clean_detections_are_tracked_within_20_mm(clean_error):
    assert clean_error < 20.0


def test_ten_percent_false_positives_change_the_error_little(body, rig, clean_error):
    noisy = walk(body, rig, false_positive_rate=0.1)
    assert len(noisy.detections) > 1.05 * FRAMES * 4 * 21
    err, _ = tracking_error(body, noisy, tracker(body, rig))
    assert err < clean_error + 8.0


def test_a_marker_left_in_two_views_is_reported_and_still_tracked(body, rig, clean):
    det = clean.detections
    lab = det.labels.index("l_elbow")
    drop = (det.label == lab) & (det.view >= 2)
    keep = ~drop
    seq = Sequence(clean.name, clean.rig, clean.fps,
                   detections=Detections(det.labels, det.frame[keep], det.view[keep], det.label[keep],
                                         det.xy[keep], det.confidence[keep]), gt=clean.gt)
    err, estimates = tracking_error(body, seq, tracker(body, rig))
    d = estimates[-1].diagnostics
    assert d["views_per_landmark"]["l_elbow"] == 2 and d["weak_landmarks"] == ["l_elbow"]
    assert d["energy_terms"]["coherence"] >= 0.0
    assert err < 25.0
    assert d["landmarks"].shape == (21, 3) and d["energy_evaluations"] == 100 * 6


def test_the_tracker_initialises_itself_from_labelled_detections(body, rig, clean):
    trk = tracker(body, rig)
    chi, alpha = trk.initial_estimate(frame_of(clean, 0))
    err = joint_errors(body.shaped(alpha).joints(chi), clean.gt.joints[:1], body.joint_names).mean()
    assert err < 30.0
    rest_est, rest_gt = body.rest(alpha)[1], body.rest(clean.gt.alpha)[1]
    height = lambda j: j[:, 2].max() - j[:, 2].min()                    # noqa: E731
    assert abs(height(rest_est) - height(rest_gt)) < 0.03


def test_frames_without_detections_fail_with_a_clear_message(body, rig, clean):
    trk = tracker(body, rig)
    trk.initialize(clean.gt.chi[0], clean.gt.alpha)
    with pytest.raises(ValueError, match="needs 2D detections"):
        trk.step(Frame(index=1, masks=np.zeros((4, 480, 640), bool)))


def test_numpy_fallbacks_track_as_the_compiled_annealing_does(body, rig, clean, monkeypatch):
    """The compiled annealing pieces (betas, spreads, root maps, association) and their numpy
    fallbacks (numba missing) give the same estimates over several frames, to rounding: the
    same algorithm, not merely a similar one."""
    from mocap.body import root_motion
    from mocap.trackers import apf
    from mocap.trackers.markers import refine

    if not apf.HAVE_NUMBA:
        pytest.skip("numba is not installed")

    def run():
        trk = tracker(body, rig)
        trk.initialize(clean.gt.chi[0], clean.gt.alpha)
        return np.array([trk.step(frame_of(clean, t)).chi for t in range(1, 7)])

    compiled = run()
    for module in (apf, root_motion, refine):
        monkeypatch.setattr(module, "HAVE_NUMBA", False)
    fallback = run()
    # rounding differences (1e-16) grow through the refinement's finite-difference Jacobian
    # (step 1e-4) to ~1e-8; a different resampling or bisection would differ by ~1e-3
    np.testing.assert_allclose(fallback, compiled, rtol=0, atol=1e-7)
