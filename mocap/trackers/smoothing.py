"""An offline zero-phase smoother of a finished track (issue 34 item 4): the tracked pose
parameters, root and joint angles, low-pass filtered forward and backward with a Butterworth
filter (``scipy.signal.filtfilt``), the standard step after markerless motion capture (Pose2Sim's
default: 4th order, 6 Hz). The keypoints' frame-to-frame noise, which the local step passes on to
the pose, is damped; slow motion passes, and the forward-backward pass adds no lag.

The root (the twist chi[:6] of the body's rigid motion) is filtered as what it moves: its
translation component-wise, its rotation as a unit quaternion made sign-continuous from frame to
frame (q and -q are one rotation) and normalised after the filter; the joint angles are filtered
component-wise and clipped to the body's limits. The shape is not touched.

:func:`smooth_poses` is the math (poses (F, D) in, poses (F, D) out); :func:`smooth_track` applies
it to one person's estimates, as a tracker's :meth:`final_tracks` does with
:class:`TrackSmoothing` on (``tracker.smoothing.cutoff_hz`` > 0).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mocap.trackers.tracker_settings import TrackSmoothing

__all__ = ["TrackSmoothing", "continuous_quaternions", "filter_pad", "lowpass", "smooth_poses",
           "smooth_track"]


def filter_pad(order: int) -> int:
    """Frames the filter extends each end by: 3 x (order + 1) (scipy's default); a track no longer
    than this is left as it is."""
    return 3 * (int(order) + 1)


def lowpass(x: np.ndarray, cutoff_hz: float, fps: float, order: int = 4) -> np.ndarray:
    """x (F, n) filtered along frames by a Butterworth low-pass of ``order`` at ``cutoff_hz``,
    forward and backward (zero phase), odd-extended at both ends by 3 x (order + 1) frames
    (scipy's default). A cut-off at or above the Nyquist frequency (fps / 2), or a track no longer
    than that extension (too short for the filter's start-up: it would add error, not remove it),
    leaves x as it is. -> (F, n) float64."""
    from scipy.signal import butter, filtfilt

    x = np.asarray(x, np.float64)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"smoothing: the frame rate must be a number > 0, got {fps!r}")
    wn = float(cutoff_hz) / (0.5 * float(fps))
    pad = filter_pad(order)
    if len(x) <= pad or wn >= 1.0:
        return x.copy()
    b, a = butter(int(order), wn)
    return filtfilt(b, a, x, axis=0, padtype="odd", padlen=pad)


def continuous_quaternions(R: np.ndarray) -> np.ndarray:
    """Rotations R (F, 3, 3) as unit quaternions (F, 4) (x, y, z, w)
    (:func:`mocap.export.axes.quaternions_from_rotations`, the project's one conversion), each
    one's sign chosen nearest the previous frame's (q and -q are one rotation)."""
    from mocap.export.axes import quaternions_from_rotations

    q = quaternions_from_rotations(R)
    for f in range(1, len(q)):
        if np.dot(q[f], q[f - 1]) < 0:
            q[f] = -q[f]
    return q


def smooth_poses(chis: np.ndarray, limits: np.ndarray, fps: float, settings: TrackSmoothing) -> np.ndarray:
    """Poses chis (F, D) (chi[:6]: the root's twist (v, omega), chi[6:]: joint angles, rad) low-pass
    filtered along frames (:func:`lowpass`): the root's translation and its rotation's
    sign-continuous quaternion, renormalised, then back to a twist; the joint angles, then clipped
    to ``limits`` (D, 2). settings off: chis unchanged. -> (F, D) float64."""
    from scipy.spatial.transform import Rotation

    from mocap.body.twists import se3_exp, se3_log

    chis = np.asarray(chis, np.float64)
    if not settings.enabled:
        return chis.copy()
    if chis.ndim != 2 or chis.shape[1] < 6 or not np.all(np.isfinite(chis)):
        raise ValueError(f"smoothing: poses must be finite (F, D >= 6), got shape {chis.shape}")
    f = (settings.cutoff_hz, fps, settings.order)
    T = se3_exp(chis[:, :6])                                                    # (F, 4, 4)
    t = lowpass(T[:, :3, 3], *f)                                                # (F, 3)
    q = lowpass(continuous_quaternions(T[:, :3, :3]), *f)                       # (F, 4)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    out = np.empty_like(chis)
    Ts = np.tile(np.eye(4), (len(chis), 1, 1))
    Ts[:, :3, :3] = Rotation.from_quat(q).as_matrix()
    Ts[:, :3, 3] = t
    out[:, :6] = se3_log(Ts)
    lo, hi = np.asarray(limits, np.float64)[6:, 0], np.asarray(limits, np.float64)[6:, 1]
    out[:, 6:] = np.clip(lowpass(chis[:, 6:], *f), lo, hi)
    return out


def smooth_track(track: dict, limits: np.ndarray, fps: float, settings: TrackSmoothing) -> dict:
    """One person's track {frame: Estimate} with its poses smoothed (:func:`smooth_poses`, over
    its frames in order; shapes and diagnostics as tracked); settings off: the track itself."""
    if not settings.enabled or len(track) < 2:
        return track
    frames = sorted(track)
    chis = smooth_poses(np.stack([track[f].chi for f in frames]), limits, fps, settings)
    return {f: dataclasses.replace(track[f], chi=c) for f, c in zip(frames, chis, strict=True)}
