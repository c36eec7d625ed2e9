"""The two-cue hybrid's shape fitted over many frames to both cues at once
(``keypoints.two_cue``, mocap/trackers/two_cue_shape.py): the bone lengths' evidence is the
frames' count over their spread, the search's coordinates are the keypoints' posterior, and on a
known body the fit to silhouettes and noisy keypoints together is closer than either alone; off
(the default), the hybrid is unchanged."""

import numpy as np
import pytest

from mocap.body.catalogue import make_landmark_set, probe_poses
from mocap.trackers.keypoint_cue import KeypointCue
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of, track_sequence
from mocap.trackers.tracker_settings import KeypointSettings, TwoCueShape
from mocap.trackers.two_cue_shape import TwoCueState, fit_two_cue_shape, length_evidence
from tests.trackers.test_hybrid_kp import keypoint_walk
from tests.trackers.test_keypoint_shape_frames import LABELS

FAST = {"local": {"iterations": 3}, "apf": {"particles": 10, "layers": 3}}


def rest_error_mm(body, alpha, truth) -> float:
    """Mean distance (mm) between the rest meshes of two shapes."""
    v = body.rest(np.stack([np.asarray(alpha, np.float64), np.asarray(truth, np.float64)]))[0]
    return 1000 * float(np.linalg.norm(v[0] - v[1], axis=1).mean())


def test_the_length_evidence_is_the_frames_count_over_their_spread(body):
    """Landmarks of one body in 40 poses with 1 cm Gaussian noise per coordinate: each bone's
    median is its true length within 4 standard errors, its spread the length's noise (the
    difference of two 3D points: sqrt(2) cm along the bone) within 25 %, the count 40; with
    no noise (pairs rigid to 0.1 mm: skinned landmarks) the spread is the floor and the energy at
    the true shape near none."""
    landmarks = make_landmark_set(body, "auto", LABELS)
    alpha = np.random.default_rng(0).normal(0.0, 1.0, body.num_shape)
    clean = np.asarray(landmarks.positions(body.shaped(alpha), probe_poses(body, 40)), np.float64)
    noisy = clean + np.random.default_rng(1).normal(0.0, 0.01, clean.shape)
    ev = length_evidence(body, landmarks, noisy, floor=0.001)
    true = ev.lengths(alpha)[0]
    assert len(ev.pairs) >= 8 and np.all(ev.count == 40)
    assert np.all(np.abs(ev.median - true) < 4 * 1.25 * ev.spread / np.sqrt(40))
    assert np.median(ev.spread) == pytest.approx(0.01 * np.sqrt(2), rel=0.25)
    assert np.allclose(ev.weight, 40 / ev.spread**2)
    exact = length_evidence(body, landmarks, clean, floor=0.003)
    assert np.allclose(exact.spread, 0.003) and np.allclose(exact.median, true, atol=1e-4)
    assert exact.energy(alpha[None])[0] < 1e-2 * exact.energy(np.zeros((1, body.num_shape)))[0]


def test_the_keypoints_fit_and_its_posterior_match_a_linear_least_squares(body):
    """The Gauss-Newton fit is where the energy's gradient vanishes (finite differences), and the
    posterior root R satisfies R R = (J^T J + I)^-1."""
    landmarks = make_landmark_set(body, "auto", LABELS)
    alpha = np.random.default_rng(2).normal(0.0, 1.0, body.num_shape)
    pts = np.asarray(landmarks.positions(body.shaped(alpha), probe_poses(body, 6)), np.float64)
    ev = length_evidence(body, landmarks, pts + np.random.default_rng(3).normal(0, 0.005, pts.shape), 0.005)
    C = 8
    fit = ev.fit(np.zeros(body.num_shape), C)

    def total(a):
        return ev.energy(a[None])[0] + 0.5 * float((a[:C] ** 2).sum())

    for k in range(C):
        step = np.zeros(body.num_shape)
        step[k] = 1e-5
        assert abs((total(fit + step) - total(fit - step)) / 2e-5) < 1e-2 * max(1.0, abs(total(fit)))
    assert np.all(fit[C:] == 0)
    J = ev.jacobian(fit, C)
    R = ev.posterior_root(fit, C)
    assert np.allclose(R, R.T) and np.allclose(R @ R, np.linalg.inv(J.T @ J + np.eye(C)), atol=1e-10)


def test_the_prior_weight_scales_the_prior_and_at_zero_gives_the_least_squares_lengths(body):
    """``prior`` p: the fit is where the gradient of E + p |alpha_1..C|^2 / 2 vanishes (finite
    differences, p = 0.3), and the posterior root's square is (J^T J + p I)^-1. A body of known
    shape (its first 10 coefficients 2.5 standard deviations out, the rest 0), its landmarks
    exact in 6 poses: with p = 0 (least squares) the fit from the mean shape over those 10
    coefficients reproduces every bone length within 0.1 mm (the true shape has none left); the
    model's prior (p = 1) leaves them further off (it pulls towards the mean)."""
    landmarks = make_landmark_set(body, "auto", LABELS)
    C = 10
    truth = np.zeros(body.num_shape)
    truth[:C] = 2.5 * np.where(np.arange(C) % 2, -1.0, 1.0)
    pts = np.asarray(landmarks.positions(body.shaped(truth), probe_poses(body, 6)), np.float64)
    ev = length_evidence(body, landmarks, pts, floor=0.005)
    true = ev.lengths(truth)[0]
    lsq = ev.fit(np.zeros(body.num_shape), C, iterations=50, prior=0.0)
    assert np.abs(ev.lengths(lsq)[0] - true).max() < 1e-4
    held = ev.fit(np.zeros(body.num_shape), C, iterations=50, prior=1.0)
    assert np.abs(ev.lengths(held)[0] - true).max() > 10 * np.abs(ev.lengths(lsq)[0] - true).max()
    noise = np.random.default_rng(4).normal(0, 0.005, pts.shape)
    noisy = length_evidence(body, landmarks, pts + noise, 0.005)
    p = 0.3
    fit = noisy.fit(np.zeros(body.num_shape), C, prior=p)

    def total(a):
        return noisy.energy(a[None])[0] + 0.5 * p * float((a[:C] ** 2).sum())

    for k in range(C):
        step = np.zeros(body.num_shape)
        step[k] = 1e-5
        assert abs((total(fit + step) - total(fit - step)) / 2e-5) < 1e-2 * max(1.0, abs(total(fit)))
    J = noisy.jacobian(fit, C)
    R = noisy.posterior_root(fit, C, prior=p)
    assert np.allclose(R @ R, np.linalg.inv(J.T @ J + p * np.eye(C)), atol=1e-10)


@pytest.fixture(scope="module")
def walk(body):
    return keypoint_walk(body, 8)


def test_both_cues_recover_a_known_shape_better_than_either_alone(body, walk):
    """Our own body with a known shape: keypoints with 1 px noise and 10 % false positives in 8
    frames of 6 views (200x150 px; alone they leave the girth to the prior), the exact silhouette
    of one of those views in one frame (pose as true; alone it leaves the depth ambiguous): from
    the mean shape, the fit to both (the view counted as 4 samples) is closer to the true rest
    mesh (10 shape coefficients fitted of 20: the floor is 0.4 mm) than the keypoints' alone and
    the silhouette's alone (by 5 %: 6.1 against 6.6 and 8.4 mm), and each is closer than the
    start (33 mm) by half."""
    cue = KeypointCue(body, walk.rig, KeypointSettings(weight=200.0))
    measured = np.stack([cue.triangulated(cue.observe(frame_of(walk, f))) for f in range(8)])
    views, keys = [1], [3]
    chis, masks = walk.gt.chi[keys], [walk.masks[f][views] for f in keys]
    start = np.zeros(body.num_shape)
    settings = TwoCueShape(frames=8, view_samples=4.0)

    def fitted(m, s):
        return fit_two_cue_shape(body, walk.rig[views], cue.landmarks, start, m, chis, masks, s,
                                 np.random.default_rng(0))

    both = fitted(measured, settings)
    alone_kp = fitted(measured, TwoCueShape(frames=8, view_samples=0.0))
    alone_sil = fitted(measured[:0], settings)
    err = {name: rest_error_mm(body, f.alpha, walk.gt.alpha)
           for name, f in (("both", both), ("keypoints", alone_kp), ("silhouettes", alone_sil))}
    assert err["both"] < 0.95 * min(err["keypoints"], err["silhouettes"]), err
    assert max(err.values()) < 0.5 * rest_error_mm(body, start, walk.gt.alpha), err
    assert both.report["keyframes"] == 1 and both.report["views"] == 1
    assert alone_kp.report["after"]["silhouettes"] == 0.0 and alone_sil.report["bones"] == 0


def test_hybrid_kp_fits_its_shape_to_both_cues_after_its_keypoint_refit_frames():
    """The preset: the two-cue fit on, after the frames of the keypoint refit it replaces, every
    one of them in the silhouette term."""
    from mocap.trackers.presets import (
        KEYPOINT_SHAPE_FRAMES,
        PRESETS,
        TWO_CUE_QUADRATIC,
        TWO_CUE_SKELETON,
        TWO_CUE_SKELETON_REFIT,
        TWO_CUE_VIEW_SAMPLES,
    )

    two_cue = PRESETS["hybrid_kp"].keypoints.two_cue
    assert two_cue.enabled and two_cue.frames == two_cue.keyframes == KEYPOINT_SHAPE_FRAMES
    assert not two_cue.aligned_only and two_cue.view_samples == TWO_CUE_VIEW_SAMPLES
    assert two_cue.quadratic == TWO_CUE_QUADRATIC > 0 and TwoCueShape().quadratic == 0
    assert two_cue.skeleton == TWO_CUE_SKELETON > 0 and two_cue.skeleton_refit == TWO_CUE_SKELETON_REFIT > 0
    assert TwoCueShape().skeleton == 0 and TwoCueShape().skeleton_refit == 0
    assert not PRESETS["hybrid"].keypoints.two_cue.enabled


def test_the_state_fits_once_after_its_frames_or_every_k(body):
    """``frames`` frames in: the first fit; then every ``every`` (0: never again); keyframes are
    the aligned frames (every frame with ``aligned_only`` off), evenly spaced down to ``keyframes``."""
    once, again = TwoCueState(TwoCueShape(frames=3, keyframes=2)), TwoCueState(TwoCueShape(frames=3, every=2))
    due = {id(once): [], id(again): []}
    for f in range(9):
        for s in (once, again):
            if s.due():
                due[id(s)].append(f)
                s.fits += 1
            s.add(f, np.zeros(3), np.zeros((1, 2, 2), bool), np.zeros((4, 3)), aligned=f != 4)
    assert due[id(once)] == [3] and due[id(again)] == [3, 5, 7]
    assert [k[0] for k in once.chosen()] == [0, 8] and len(once.keyframes) == 8
    every = TwoCueState(TwoCueShape(frames=3, keyframes=3, aligned_only=False))
    for f in range(9):
        every.add(f, np.zeros(3), np.zeros((1, 2, 2), bool), np.zeros((4, 3)), aligned=f % 2 == 0)
    assert [k[0] for k in every.chosen()] == [0, 4, 8] and len(every.keyframes) == 9


def test_the_hybrid_fits_the_shape_once_after_its_frames(body):
    """With ``two_cue.frames`` 3 (frame 0 from the start-up, then frames 1-2; ``hybrid_kp``'s is
    15) the shape changes at frame 3 and not after (the 3-frame keypoint refit, ``shape_frames``
    3 here, and the silhouette-only refinements are off), its report kept; the frames before are
    those of the run without it, bit for bit."""
    seq = keypoint_walk(body, 6)

    def run(**two_cue):
        t = make_tracker("hybrid_kp", body=body, rig=seq.rig, rng=np.random.default_rng(3), **FAST,
                         keypoints={"shape_std": 1.0, "init": True, "shape_frames": 3, "two_cue": two_cue})
        chi, alpha, _ = t.refine_initial(frame_of(seq, 0), seq.gt.chi[0], np.zeros(body.num_shape))
        return t, track_sequence(t, seq, chi, alpha).estimates

    t_on, on = run(frames=3, keyframes=3, particles=10, layers=3, polish=10)   # the schedule, not the fit
    alphas = np.stack([e.alpha for e in on])
    changed = np.flatnonzero(np.any(alphas[1:] != alphas[:-1], axis=1)) + 1
    assert changed.tolist() == [3]
    report = t_on.two_cue.reports
    assert len(report) == 1 and report[0]["frames"] == 3 and 1 <= report[0]["keyframes"] <= 3
    t_off, off = run(frames=0)
    assert t_off.two_cue is None
    for a, b in zip(on[:3], off[:3], strict=True):
        assert np.array_equal(a.chi, b.chi) and np.array_equal(a.alpha, b.alpha)
    off_alphas = np.stack([e.alpha for e in off])
    assert not np.array_equal(off_alphas[3], off_alphas[2])      # without it: the keypoint refit at 3
    assert not np.allclose(alphas[3], off_alphas[3])


def test_the_hybrid_fits_its_skeleton_with_the_shape_and_tracks_on_it(body):
    """``two_cue.skeleton`` > 0: at the two-cue fit the rest-joint corrections are fitted to the
    aligned frames' keypoints (their report: the keypoint residual lower after than before), the
    estimates from then on carry them and the tracker's body is the corrected one (its rest joints
    the shape's plus them, its rest mesh the shape's); the frames before are the run's without
    them, bit for bit, and off (0, the dataclass's) no estimate carries any."""
    seq = keypoint_walk(body, 6)

    def run(**two_cue):
        t = make_tracker("hybrid_kp", body=body, rig=seq.rig, rng=np.random.default_rng(3), **FAST,
                         keypoints={"shape_std": 1.0, "init": True, "shape_frames": 3,
                                    "two_cue": {"frames": 3, "keyframes": 3, "particles": 10, "layers": 3,
                                                "polish": 10, "quadratic": 0, **two_cue}})
        chi, alpha, _ = t.refine_initial(frame_of(seq, 0), seq.gt.chi[0], np.zeros(body.num_shape))
        return t, track_sequence(t, seq, chi, alpha).estimates

    assert TwoCueShape().skeleton == 0.0
    t_on, on = run(skeleton=0.03, skeleton_refit=0)
    t_off, off = run(skeleton=0.0)
    t_re, re = run(skeleton=0.03, skeleton_refit=1)          # the poses re-fitted first: another answer
    assert not np.array_equal(t_re.joint_offsets, t_on.joint_offsets)
    assert all(np.array_equal(e.joint_offsets, t_re.joint_offsets) for e in re[3:])
    assert all(e.joint_offsets is None for e in off) and t_off.joint_offsets is None
    assert all(e.joint_offsets is None for e in on[:3])
    d = t_on.joint_offsets
    assert d.shape == (body.num_joints, 3) and np.abs(d).max() > 0
    assert all(np.array_equal(e.joint_offsets, d) for e in on[3:])
    shaped = t_on.shaped
    plain = body.shaped(shaped.alpha)
    np.testing.assert_array_equal(shaped.rest_vertices, plain.rest_vertices)
    np.testing.assert_allclose(shaped.rest_joints, plain.rest_joints + d, atol=1e-6)
    report = t_on.two_cue.reports[0]["skeleton"]
    assert report["rms_after_mm"] < report["rms_before_mm"] and report["observations"] > 0
    for a, b in zip(on[:3], off[:3], strict=True):
        assert np.array_equal(a.chi, b.chi) and np.array_equal(a.alpha, b.alpha)
