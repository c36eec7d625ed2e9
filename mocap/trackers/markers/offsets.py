"""Keypoint-to-landmark offsets learned while tracking.

A detector's keypoint is not exactly our landmark: OpenPose's hips sit higher and wider than
the hip joint centres, and a body that our shape space cannot reproduce puts its knees or
shoulders centimetres from where our model's joints are. With the offset o_l constant in the
frame of the landmark's joint, the keypoint is G_j(chi) (r_l + o_l). Over the first
``frames`` tracked frames every keypoint is triangulated robustly
(:func:`mocap.trackers.markers.startup.triangulate_candidates`) and brought into its joint's rest
frame with the tracker's estimate: o_l = median_t G_j(chi_t)^-1 X_l,t - r_l (needs
``min_samples`` frames), its norm clipped to ``max_norm`` metres. From then on the
likelihood projects r_l + o_l: the pose is fitted to what the detector marks, and the
estimate's landmarks (diagnostics, and :meth:`MarkerEnergy.points`) are the keypoints.

Offsets that a change of pose can mimic (the hips and the mid-hip all higher: the body a little
higher or tilted) cannot be told apart from the pose by the detections alone: the tracker's pose
absorbs them before they are learned. A **detector profile** is the prior knowledge that tells
them apart: the mean offsets of a detector's keypoints from the anatomical joints, calibrated
on data with ground truth (:data:`~mocap.trackers.markers.settings.PROFILES`, in the keypoint frames of
:func:`mocap.data.detector_semantics.keypoint_frames`). With a profile (the marker tracker's
``keypoint_profile``) the start-up removes the profile's offsets from the triangulated
keypoints before it fits the shape and pose (:func:`remove_profile`), tracking starts with the
profile's offsets in the rest frames (:func:`profile_rest_offsets`), and online learning adds
the sequence's own residual offsets on top.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from mocap.data.detector_semantics import keypoint_frames, local_offsets
from mocap.trackers.markers.settings import PROFILES  # noqa: F401  (re-exported)
from mocap.trackers.tracker_settings import OffsetLearning


def local_residuals(transforms: np.ndarray, points: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """G^-1 X - r per landmark: transforms (L, 4, 4) of each landmark's joint, points (L, 3)
    world (NaN: unmeasured), rest (L, 3) -> (L, 3) rest-frame offsets (NaN where unmeasured)."""
    R, t = transforms[:, :3, :3], transforms[:, :3, 3]
    return np.einsum("lji,lj->li", R, points - t) - rest


def offset_significance(samples: np.ndarray) -> np.ndarray:
    """(T, L, 3) per-frame residuals (NaN: unmeasured) -> (L,) how far each landmark's median
    residual is from zero against its own noise: sqrt(sum over axes (median / se)^2), se the
    median's standard error from the per-frame spread, 1.2533 x 1.4826 MAD / sqrt(n) (Gaussian
    frames). Pure noise gives ~sqrt(3) (a chi with 3 degrees of freedom); a constant offset
    grows with sqrt(n). 0 where fewer than 2 frames measured the landmark; a spread of 0 counts
    as 1 micrometre."""
    samples = np.asarray(samples, np.float64)
    n = np.isfinite(samples[..., 0]).sum(axis=0)                                   # (L,)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # a landmark measured in no frame
        med = np.nanmedian(samples, axis=0)                                        # (L, 3)
        mad = np.nanmedian(np.abs(samples - med), axis=0)
    se = 1.2533 * np.maximum(1.4826 * mad, 1e-6) / np.sqrt(np.maximum(n, 1))[:, None]
    z = np.sqrt(np.nansum((med / se) ** 2, axis=1))
    return np.where(n >= 2, z, 0.0)


def robust_offsets(samples: np.ndarray, settings: OffsetLearning) -> np.ndarray:
    """(T, L, 3) per-frame residuals -> (L, 3) offsets (zero where too few samples, and where
    the median is not ``settings.significance`` standard errors from zero:
    :func:`offset_significance`; 0 keeps every median)."""
    have = np.isfinite(samples[..., 0]).sum(axis=0) >= settings.min_samples
    if settings.significance > 0:
        have &= offset_significance(samples) >= settings.significance
    with np.errstate(all="ignore"):
        o = np.nanmedian(np.where(have[None, :, None], samples, 0.0), axis=0)
    o = np.where(have[:, None] & np.isfinite(o), o, 0.0)
    n = np.linalg.norm(o, axis=1, keepdims=True)
    return o * np.minimum(1.0, settings.max_norm / np.maximum(n, 1e-12))


def profile_table(profile: str | Mapping) -> dict:
    """A profile's table (keypoint type -> (out, forward, up) mm) from its name or the table."""
    if isinstance(profile, str):
        if profile not in PROFILES:
            raise ValueError(f"keypoint_profile must be null, one of {sorted(PROFILES)} or a table "
                             f"keypoint type -> [out, forward, up] mm, got {profile!r}")
        return PROFILES[profile]
    return {str(k): tuple(float(x) for x in v) for k, v in dict(profile).items()}


def profile_rest_offsets(profile: str | Mapping, names: Sequence[str], rest: np.ndarray) -> np.ndarray:
    """(L, 3) offsets in the rest frames of landmarks ``names`` at rest positions ``rest`` (L, 3)."""
    frames = keypoint_frames(np.asarray(rest, np.float64)[None], names)[0]
    return np.einsum("lab,lb->la", frames, local_offsets(names, profile_table(profile)))


def remove_profile(profile: str | Mapping, names: Sequence[str], points: np.ndarray) -> np.ndarray:
    """Measured keypoints (L, 3) world (NaN: unmeasured) minus the profile's offsets in their
    own keypoint frames: estimates of the anatomical points (NaN where a frame's torso points
    are unmeasured)."""
    frames = keypoint_frames(np.asarray(points, np.float64)[None], names)[0]
    return points - np.einsum("lab,lb->la", frames, local_offsets(names, profile_table(profile)))
