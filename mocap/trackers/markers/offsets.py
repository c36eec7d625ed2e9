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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocap.settings import check


@dataclass(frozen=True)
class OffsetLearning:
    """frames: tracked frames to learn from (0: off); max_norm: metres; min_samples: per
    landmark."""

    frames: int = 0
    max_norm: float = 0.08
    min_samples: int = 3

    def __post_init__(self) -> None:
        check(self, "frames", self.frames >= 0, "an integer >= 0 (0: off)")
        check(self, "max_norm", self.max_norm >= 0, ">= 0 m")
        check(self, "min_samples", self.min_samples >= 1, "an integer >= 1")


def local_residuals(transforms: np.ndarray, points: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """G^-1 X - r per landmark: transforms (L, 4, 4) of each landmark's joint, points (L, 3)
    world (NaN: unmeasured), rest (L, 3) -> (L, 3) rest-frame offsets (NaN where unmeasured)."""
    R, t = transforms[:, :3, :3], transforms[:, :3, 3]
    return np.einsum("lji,lj->li", R, points - t) - rest


def robust_offsets(samples: np.ndarray, settings: OffsetLearning) -> np.ndarray:
    """(T, L, 3) per-frame residuals -> (L, 3) offsets (zero where too few samples)."""
    have = np.isfinite(samples[..., 0]).sum(axis=0) >= settings.min_samples
    with np.errstate(all="ignore"):
        o = np.nanmedian(np.where(have[None, :, None], samples, 0.0), axis=0)
    o = np.where(have[:, None] & np.isfinite(o), o, 0.0)
    n = np.linalg.norm(o, axis=1, keepdims=True)
    return o * np.minimum(1.0, settings.max_norm / np.maximum(n, 1e-12))
