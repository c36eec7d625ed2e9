"""The finished track's zero-phase smoother (:mod:`mocap.trackers.smoothing`, issue 34 item 4):
known answers of the Butterworth filter (a sine at the cut-off comes out at half its amplitude, the
forward-backward pass's squared gain, with no lag; a slow one passes; noise about a known signal
shrinks), the root's rotation filtered through +-pi without a jump, the joint angles kept within
their limits, bad settings refused, and a run with it on holds one track: what the recording
saw, motion.npz and the metrics are the smoothed poses."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import butter, freqz

from mocap.body.twists import se3_exp
from mocap.settings import SettingError
from mocap.trackers.smoothing import TrackSmoothing, lowpass, smooth_poses, smooth_track
from mocap.trackers.tracker_settings import HybridSettings, LocalSettings

FPS = 30.0


def _interior(x: np.ndarray, margin: int = 30) -> np.ndarray:
    return x[margin:-margin]


def test_a_sine_at_the_cutoff_comes_out_at_the_squared_gain_with_no_lag():
    t = np.arange(300) / FPS
    for cutoff, freq in ((4.0, 4.0), (6.0, 2.0), (3.0, 5.0)):
        x = np.sin(2 * np.pi * freq * t + 0.3)[:, None]
        y = lowpass(x, cutoff, FPS, order=4)
        b, a = butter(4, cutoff / (FPS / 2))
        gain = np.abs(freqz(b, a, worN=[2 * np.pi * freq / FPS])[1][0]) ** 2   # forward and back
        if freq == cutoff:
            assert gain == pytest.approx(0.5, abs=1e-9)        # Butterworth: -3 dB each way
        # zero phase: y is exactly gain * x in the steady state
        np.testing.assert_allclose(_interior(y), gain * _interior(x), atol=2e-3)


def test_slow_motion_passes_and_noise_about_it_shrinks():
    rng = np.random.default_rng(0)
    t = np.arange(60) / FPS
    truth = np.stack([np.sin(2 * np.pi * 0.7 * t + 1), 0.5 * t, np.cos(2 * np.pi * 0.3 * t)], 1)
    np.testing.assert_allclose(_interior(lowpass(truth, 4.0, FPS), 10), _interior(truth, 10), atol=2e-3)
    np.testing.assert_allclose(lowpass(truth, 4.0, FPS), truth, atol=1e-2)     # the ends: odd-extended
    errs = []
    for _ in range(50):
        noisy = truth + rng.normal(0, 0.05, truth.shape)
        errs.append((np.abs(noisy - truth).mean(), np.abs(lowpass(noisy, 4.0, FPS) - truth).mean()))
    before, after = np.mean(errs, axis=0)
    # white noise through a 4 Hz low-pass at 30 fps keeps about sqrt(4 / 15) of its std, and
    # the signal passes: the error falls by about half
    assert after < 0.65 * before


def test_too_short_a_track_or_a_cutoff_above_nyquist_is_left_as_it_is():
    x = np.random.default_rng(1).normal(size=(15, 3))
    np.testing.assert_array_equal(lowpass(x, 3.0, FPS), x)              # <= 3 (order + 1) frames
    y = np.random.default_rng(1).normal(size=(40, 3))
    np.testing.assert_array_equal(lowpass(y, 15.0, FPS), y)             # at Nyquist
    assert not np.array_equal(lowpass(y, 3.0, FPS), y)


def test_the_root_turning_through_pi_is_smoothed_without_a_jump(body):
    rng = np.random.default_rng(2)
    F = 60
    heading = np.linspace(2.0, 4.5, F)                 # through pi: the rotation vector flips
    chis = np.zeros((F, body.num_dofs))
    chis[:, 5] = np.where(heading > np.pi, heading - 2 * np.pi, heading)
    chis[:, 0] = np.linspace(0.0, 1.0, F)
    clean = se3_exp(chis[:, :6])
    noisy = chis.copy()
    noisy[:, 3:6] += rng.normal(0, 0.02, (F, 3))
    out = smooth_poses(noisy, body.limits, FPS, TrackSmoothing(cutoff_hz=3.0))
    T = se3_exp(out[:, :6])
    rot_err = np.linalg.norm(T[:, :3, :3] - clean[:, :3, :3], axis=(1, 2))
    noisy_err = np.linalg.norm(se3_exp(noisy[:, :6])[:, :3, :3] - clean[:, :3, :3], axis=(1, 2))
    assert rot_err.max() < 0.05 and rot_err.mean() < 0.6 * noisy_err.mean()
    # the translation (not the twist's v, which moves with the rotation) is the one filtered
    np.testing.assert_allclose(T[:, :3, 3], lowpass(se3_exp(noisy[:, :6])[:, :3, 3], 3.0, FPS), atol=1e-9)


def test_joint_angles_are_filtered_and_kept_within_their_limits(body):
    rng = np.random.default_rng(3)
    F = 40
    chis = np.zeros((F, body.num_dofs))
    hi = body.limits[6:, 1]
    chis[:, 6:] = np.clip(hi - 0.01 + rng.normal(0, 0.05, (F, body.num_dofs - 6)), body.limits[6:, 0], hi)
    out = smooth_poses(chis, body.limits, FPS, TrackSmoothing(cutoff_hz=3.0))
    assert np.all(out[:, 6:] <= hi) and np.all(out[:, 6:] >= body.limits[6:, 0])
    free = np.clip(lowpass(chis[:, 6:], 3.0, FPS), body.limits[6:, 0], hi)
    np.testing.assert_allclose(out[:, 6:], free, atol=1e-12)
    assert np.array_equal(smooth_poses(chis, body.limits, FPS, TrackSmoothing()), chis)       # off


@pytest.mark.parametrize("field,value", [("cutoff_hz", -1.0), ("cutoff_hz", float("nan")), ("cutoff_hz", "4"),
                                         ("order", 0), ("order", 2.5)])
def test_bad_smoothing_settings_are_refused_naming_the_field(field, value):
    with pytest.raises(SettingError, match=field):
        TrackSmoothing(**{field: value})


def test_the_trackers_settings_hold_it_off_by_default():
    assert not HybridSettings().smoothing.enabled and not LocalSettings().smoothing.enabled


def test_a_run_with_smoothing_records_writes_and_scores_the_smoothed_track(body, tmp_path, monkeypatch):
    """A local tracker answering each frame with its ground truth plus known noise (its step
    replaced; the rest is the local tracker's: check_sequence, final_tracks): the recording sees
    the smoothed poses, motion.npz holds them and the metrics score them."""
    import mocap
    import mocap.run_folder.tracking as tracking
    from mocap.export.motion import read_motion_npz
    from mocap.recording.sink import NullSink
    from mocap.run_folder import run_tracking
    from mocap.trackers.base import Estimate
    from mocap.trackers.local_tracker import LocalTracker

    F = 20
    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=F, seed=0)
    noise = np.random.default_rng(4).normal(0, 0.02, (F, body.num_dofs))
    noise[:, :6] = 0.0
    answered = np.clip(seq.gt.chi[:F] + noise, body.limits[:, 0], body.limits[:, 1])

    class Noisy(LocalTracker):
        def step(self, frame):
            return Estimate(chi=answered[frame.index].copy(), alpha=seq.gt.alpha)

    recorded = {}

    class Capture(NullSink):
        def frame(self, frame, estimate, joints, vertices, truth_joints, error_mm, seconds):
            recorded[frame.index] = np.array(estimate.chi)

    monkeypatch.setattr(tracking, "make_sink", lambda out_dir, settings: Capture())
    settings = LocalSettings(smoothing=TrackSmoothing(cutoff_hz=4.0))
    config = {"seed": 0, "frames": None, "threads": 1,
              "init": {"mode": "gt_noise", "noise_deg": 0.0, "noise_translation": 0.0, "cache": None},
              "recording": {"enabled": False}, "motion": {"vertices": False}, "oracle": {"enabled": False}}
    metrics = run_tracking(tmp_path / "run", config, make_body=lambda: body, make_sequence=lambda b: seq,
                           make_tracker=lambda body, rig, rng, keep_particles: Noisy(body, rig, settings))
    _, arrays = read_motion_npz(tmp_path / "run")
    start = np.clip(seq.gt.chi[0], body.limits[:, 0], body.limits[:, 1])
    expected = smooth_poses(np.vstack([start[None], answered[1:]]), body.limits, seq.fps, settings.smoothing)
    np.testing.assert_allclose(arrays["chi"], expected, atol=1e-9)
    np.testing.assert_allclose(np.stack([recorded[f] for f in range(F)]), expected, atol=1e-9)
    from mocap.eval.run_metrics import accuracy_metrics

    again = accuracy_metrics(body, seq, expected, np.tile(seq.gt.alpha, (F, 1)), {"enabled": False})
    assert metrics["mpjpe_mm"] == pytest.approx(again["mpjpe_mm"], abs=1e-6)
    raw = accuracy_metrics(body, seq, np.vstack([start[None], answered[1:]]), np.tile(seq.gt.alpha, (F, 1)),
                           {"enabled": False})
    assert metrics["mpjpe_mm"] < raw["mpjpe_mm"]            # the noise was damped
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["mpjpe_mm"] == metrics["mpjpe_mm"]


def test_smooth_track_keeps_shapes_and_diagnostics_and_orders_frames(body):
    from mocap.trackers.base import Estimate

    rng = np.random.default_rng(5)
    chis = rng.normal(0, 0.01, (30, body.num_dofs))
    track = {f: Estimate(chi=chis[f], alpha=np.full(3, f)) for f in reversed(range(30))}
    out = smooth_track(track, body.limits, FPS, TrackSmoothing(cutoff_hz=4.0))
    np.testing.assert_allclose(np.stack([out[f].chi for f in range(30)]),
                               smooth_poses(chis, body.limits, FPS, TrackSmoothing(cutoff_hz=4.0)))
    assert all(np.array_equal(out[f].alpha, np.full(3, f)) for f in range(30))
    assert smooth_track(track, body.limits, FPS, TrackSmoothing()) is track


def test_the_tracker_smooths_only_tracks_long_enough_and_needs_the_frame_rate(body):
    from mocap.cameras import ring_rig
    from mocap.trackers.base import Estimate
    from mocap.trackers.local_tracker import LocalTracker

    rig = ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=45)
    tracker = LocalTracker(body, rig, LocalSettings(smoothing=TrackSmoothing(cutoff_hz=4.0)))
    chis = np.random.default_rng(6).normal(0, 0.01, (40, body.num_dofs))
    short = {0: {f: Estimate(chi=chis[f], alpha=np.zeros(3)) for f in range(15)}}
    assert tracker.final_tracks(short) is short and tracker.revises_tracks     # 15 frames: as tracked
    long = {0: {f: Estimate(chi=chis[f], alpha=np.zeros(3)) for f in range(40)}}
    with pytest.raises(RuntimeError, match="check_sequence"):
        tracker.final_tracks(long)
    tracker.fps = FPS
    np.testing.assert_allclose(np.stack([e.chi for e in tracker.final_tracks(long)[0].values()]),
                               smooth_poses(chis, body.limits, FPS, TrackSmoothing(cutoff_hz=4.0)))
    assert not LocalTracker(body, rig).revises_tracks


def test_failure_injection_keeps_the_wrapped_trackers_smoothing(body):
    """A recovery run (``mocap recovery``: the tracker wrapped by FailureInjection) gets the wrapped
    tracker's final tracks: smoothed where it smooths, as tracked where it does not."""
    from mocap.cameras import ring_rig
    from mocap.trackers.base import Estimate
    from mocap.trackers.failures import FailureInjection
    from mocap.trackers.local_tracker import LocalTracker

    rig = ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=45)
    inner = LocalTracker(body, rig, LocalSettings(smoothing=TrackSmoothing(cutoff_hz=4.0)))
    inner.fps = FPS
    wrapped = FailureInjection(inner, body)
    chis = np.random.default_rng(7).normal(0, 0.01, (40, body.num_dofs))
    tracks = {0: {f: Estimate(chi=chis[f], alpha=np.zeros(3)) for f in range(40)}}
    assert wrapped.revises_tracks
    np.testing.assert_allclose(np.stack([e.chi for e in wrapped.final_tracks(tracks)[0].values()]),
                               smooth_poses(chis, body.limits, FPS, TrackSmoothing(cutoff_hz=4.0)))
    plain = FailureInjection(LocalTracker(body, rig), body)
    assert not plain.revises_tracks and plain.final_tracks(tracks) is tracks
