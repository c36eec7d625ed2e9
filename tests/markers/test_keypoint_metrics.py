"""Metrics without ground truth (mocap/eval/keypoint_metrics.py)."""

import numpy as np
import pytest

from mocap.cameras import project, ring_rig
from mocap.data.sequence import Detections
from mocap.eval.keypoint_metrics import (
    detection_residuals,
    jitter_mm,
    keypoint_metrics,
    triangulate_detections,
)

NAMES = ("l_shoulder", "l_elbow", "l_wrist")


def moving_arm(F=6):
    """Three landmarks translating at constant velocity (F, 3, 3): rigid, no jitter."""
    base = np.array([[0.2, 0.0, 1.4], [0.45, 0.0, 1.4], [0.7, 0.0, 1.4]])
    return base + np.arange(F)[:, None, None] * np.array([0.01, 0.005, 0.0])


def detections_of(rig, X, offset=0.0):
    F, L = X.shape[:2]
    px = project(rig, X)                                               # (F, C, L, 2)
    f, c, lm = np.meshgrid(np.arange(F), np.arange(len(rig)), np.arange(L), indexing="ij")
    n = f.size
    return Detections(NAMES, f.ravel(), c.ravel(), lm.ravel(), px.reshape(-1, 2) + offset, np.ones(n))


def test_exact_projections_have_zero_error_jitter_and_bone_variation():
    rig = ring_rig(4, 3.0, 1.5, 640, 480, fov_deg=50, look_at=(0, 0, 1.0))
    X = moving_arm()
    m = keypoint_metrics(rig, X, NAMES, detections_of(rig, X))
    assert m["reprojection_median_px"] < 1e-6 and m["jitter_mm"] < 1e-9
    assert m["bone_length_std_mm"] < 1e-9
    assert m["bone_length_mm"]["l_shoulder-l_elbow"] == pytest.approx(250.0)
    assert set(m["reprojection_median_px_per_view"]) == set(rig.names)


def test_a_constant_pixel_offset_is_the_reprojection_error_and_the_nearest_duplicate_counts():
    rig = ring_rig(3, 3.0, 1.5, 640, 480, fov_deg=50, look_at=(0, 0, 1.0))
    X = moving_arm(2)
    det = detections_of(rig, X, offset=np.array([3.0, 4.0]))
    err, view = detection_residuals(rig, X, NAMES, det)
    np.testing.assert_allclose(err, 5.0)
    far = Detections(NAMES, np.r_[det.frame, 0], np.r_[det.view, 0], np.r_[det.label, 0],
                     np.vstack([det.xy, [0.0, 0.0]]), np.r_[det.confidence, 1.0])
    assert len(detection_residuals(rig, X, NAMES, far)[0]) == len(err)   # a second detection is ignored


def test_triangulated_detections_recover_the_points_and_zigzag_is_jitter():
    rig = ring_rig(4, 3.0, 1.5, 640, 480, fov_deg=50, look_at=(0, 0, 1.0))
    X = moving_arm(4)
    np.testing.assert_allclose(triangulate_detections(rig, detections_of(rig, X), NAMES, 4), X, atol=1e-6)
    Z = X.copy()
    Z[1::2, :, 0] += 0.002                                               # +-2 mm zigzag
    assert jitter_mm(Z) == pytest.approx(4.0)      # |second difference| = 2 + 2 mm every frame
