"""The two-cue hybrid's shape fitted to the keypoints of several frames (``keypoints.shape_frames``,
mocap/trackers/keypoint_cue.py): the median of the frames' bone lengths gives the true body's
lengths where one frame's measurement is off, and the tracker changes its shape once, when the
frames are in; with 1 (the default) it tracks as before, bit for bit."""

import numpy as np
import pytest

from mocap.body.bone_lengths import length_model
from mocap.body.catalogue import make_landmark_set, probe_poses, rest_point_basis, rigid_pairs
from mocap.trackers.keypoint_cue import shape_from_frames
from mocap.trackers.markers.settings import MarkerInit
from mocap.trackers.markers.startup import shape_from_landmarks
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of, track_sequence
from tests.trackers.test_hybrid_kp import keypoint_walk

FAST = {"local": {"iterations": 3}, "apf": {"particles": 10, "layers": 3}}
LABELS = ("l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist", "l_hip", "l_knee",
          "l_ankle", "r_hip", "r_knee", "r_ankle", "neck_base", "mid_hip", "head_centre")


def rigid_length_error_mm(body, landmarks, alpha, want) -> float:
    """Mean |length - want| (mm) of the landmark pairs no pose changes, on the shape ``alpha``."""
    rest0, basis = rest_point_basis(body, landmarks)
    model = length_model(rest0, basis, rigid_pairs(body, landmarks))
    got = model.lengths(rest0 + np.einsum("k,klc->lc", alpha, basis))
    return 1000 * float(np.abs(got - want).mean())


def test_the_median_over_frames_keeps_the_true_lengths_where_one_frame_is_off(body):
    """Landmarks of a known body in 7 poses, one frame with a wrist 6 cm off (a detection's error
    that passes the outlier test): the fit to the median lengths gives the body's lengths within
    1 mm, the one-frame fit to the bad frame three times further off."""
    landmarks = make_landmark_set(body, "auto", LABELS)
    rng = np.random.default_rng(0)
    alpha = rng.normal(0.0, 1.0, body.num_shape)
    shaped = body.shaped(alpha)
    measured = np.asarray(landmarks.positions(shaped, probe_poses(body, 7)), np.float64)     # (7, L, 3)
    rest0, basis = rest_point_basis(body, landmarks)
    want = length_model(rest0, basis, rigid_pairs(body, landmarks)).lengths(measured[0])
    bad = measured.copy()
    wrist = landmarks.names.index("l_wrist")
    bad[3, wrist] += [0.06, 0.0, 0.0]
    init, prior = MarkerInit(), np.zeros(body.num_shape)
    fitted, flag = shape_from_frames(body, landmarks, bad, init, prior, 10.0)
    assert flag is None
    assert rigid_length_error_mm(body, landmarks, fitted, want) < 1.0
    one, _ = shape_from_landmarks(body, landmarks, bad[3], init.length_sigma, init.outlier_sigma,
                                  init.bound_sigma, prior_mean=prior, prior_std=10.0)
    assert rigid_length_error_mm(body, landmarks, one, want) > 3 * rigid_length_error_mm(
        body, landmarks, fitted, want)


def test_a_landmark_pair_seen_in_no_frame_leaves_the_fit_to_the_others(body):
    """NaN landmarks (never triangulated) leave their pairs out: the fit still matches the others."""
    landmarks = make_landmark_set(body, "auto", LABELS)
    alpha = np.random.default_rng(1).normal(0.0, 1.0, body.num_shape)
    measured = np.asarray(landmarks.positions(body.shaped(alpha), probe_poses(body, 4)), np.float64)
    measured[:, landmarks.names.index("head_centre")] = np.nan
    fitted, _ = shape_from_frames(body, landmarks, measured, MarkerInit(), np.zeros(body.num_shape), 10.0)
    assert np.all(np.isfinite(fitted))
    rest0, basis = rest_point_basis(body, landmarks)
    model = length_model(rest0, basis, rigid_pairs(body, landmarks))
    want = model.lengths(measured[0])
    ok = np.isfinite(want)
    got = model.lengths(rest0 + np.einsum("k,klc->lc", fitted, basis))
    assert ok.sum() >= 5 and 1000 * np.abs(got - want)[ok].mean() < 1.0


@pytest.fixture(scope="module")
def seq(body):
    return keypoint_walk(body, 6)


def run(body, seq, **keypoints):
    """Start-up refinement (with its keypoint shape fit) from the true pose and the mean shape,
    then 6 frames."""
    t = make_tracker("hybrid_kp", body=body, rig=seq.rig, rng=np.random.default_rng(3), **FAST,
                     keypoints={"shape_std": 1.0, "init": True, "two_cue": {"frames": 0}, **keypoints})
    chi, alpha, _ = t.refine_initial(frame_of(seq, 0), seq.gt.chi[0], np.zeros(body.num_shape))
    return track_sequence(t, seq, chi, alpha).estimates


def shape_changes(est) -> list[int]:
    alphas = np.stack([e.alpha for e in est])
    return (np.flatnonzero(np.abs(np.diff(alphas, axis=0)).max(axis=1) > 0) + 1).tolist()


def test_the_tracker_refits_its_shape_once_when_the_frames_are_in(body, seq):
    """shape_frames=3: the shape of frames 0-2 is the start-up's; it changes at frame 3 (fitted to
    frames 0-2) and not again. shape_frames=1: the start-up's shape throughout."""
    assert shape_changes(run(body, seq, shape_frames=3)) == [3]
    assert shape_changes(run(body, seq, shape_frames=1)) == []


def test_following_refits_on_the_current_shape_after_a_kept_silhouette_refinement(body, seq):
    """shape_follow: every frame's keypoints are kept (6 of 6, against shape_frames=3 without it);
    no silhouette refinement in 6 frames (local.shape.every 10), so the shape changes at frame 3
    only; once a silhouette refinement is kept, the next refit is the fit to all 6 frames' median
    lengths with the prior centred on the current shape (not the start's), made once."""
    t = make_tracker("hybrid_kp", body=body, rig=seq.rig, rng=np.random.default_rng(3), **FAST,
                     keypoints={"shape_std": 1.0, "init": True, "shape_frames": 3, "shape_follow": True,
                                "two_cue": {"frames": 0}})
    chi, alpha, _ = t.refine_initial(frame_of(seq, 0), seq.gt.chi[0], np.zeros(body.num_shape))
    assert shape_changes(track_sequence(t, seq, chi, alpha).estimates) == [3]
    assert len(t.cue.shape_samples) == 6
    assert t.refit_shape() is None                       # no silhouette refinement kept: no refit
    current = np.array(t.shaped.alpha, np.float64)
    want, _ = shape_from_frames(body, t.cue.landmarks, np.stack(t.cue.shape_samples), MarkerInit(), current,
                                1.0)
    t.shape_moved = True
    assert t.refit_shape()["frames"] == 6
    np.testing.assert_allclose(t.shaped.alpha, want, atol=1e-5)
    assert not np.allclose(want, current, atol=1e-3)      # the fit moved the shape
    assert t.refit_shape() is None                       # once per kept refinement


def test_without_following_only_the_first_frames_keypoints_are_kept(body, seq):
    t = make_tracker("hybrid_kp", body=body, rig=seq.rig, rng=np.random.default_rng(3), **FAST,
                     keypoints={"shape_std": 1.0, "init": True, "shape_frames": 3, "two_cue": {"frames": 0}})
    chi, alpha, _ = t.refine_initial(frame_of(seq, 0), seq.gt.chi[0], np.zeros(body.num_shape))
    track_sequence(t, seq, chi, alpha)
    assert len(t.cue.shape_samples) == 3
    t.shape_moved = True
    assert t.refit_shape() is None
