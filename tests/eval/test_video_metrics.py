"""The independent check of a tracked video against keypoints and masks."""

from __future__ import annotations

import numpy as np

from mocap.cameras import project, ring_rig
from mocap.data.sequence import Detections
from mocap.eval.video_metrics import lost_frames, offset_reprojection, silhouette_iou
from mocap.render import rasterize_silhouettes


def test_constant_offsets_are_recovered_and_removed():
    rig = ring_rig(4, 3.5, 1.5, 320, 240, fov_deg=50)
    rng = np.random.default_rng(0)
    F, names = 8, ("a", "b", "c")
    truth = rng.normal(0, 0.3, (F, 3, 3)) + [0, 0, 1.0]        # where the detector puts them
    offset = np.array([[0.05, 0, 0], [0, -0.04, 0.02], [0, 0, 0]])
    joints = truth - offset                                      # the model's joints
    px = project(rig, truth)                                     # (F, C, L, 2)
    f, c, lab = np.meshgrid(np.arange(F), np.arange(4), np.arange(3), indexing="ij")
    det = Detections(names, f.ravel(), c.ravel(), lab.ravel(), px.reshape(-1, 2), np.ones(f.size))
    out = offset_reprojection(rig, joints, names, det, px_scale=4.0)
    assert out["fitted_median_px"] < 1e-6 and out["median_px"] > 1.0
    np.testing.assert_allclose([out["offsets_mm"][n] for n in names], 1e3 * np.linalg.norm(offset, axis=1),
                               atol=1e-6)
    exact = offset_reprojection(rig, truth, names, det)
    assert exact["median_px"] < 1e-6
    assert out["median_px"] > 4 * offset_reprojection(rig, joints, names, det)["median_px"] * 0.999


def test_silhouette_iou_is_one_for_the_masks_the_body_makes(body):
    rig = ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=50)
    verts = body.shaped(np.zeros(body.num_shape)).pose(np.zeros(body.num_dofs)).vertices[0].astype(float)
    px, depth = project(rig, verts, return_depth=True)
    masks = rasterize_silhouettes(px, body.faces, 120, 160, depth, near=0.05)[None]
    np.testing.assert_allclose(silhouette_iou(verts[None], body.faces, rig, masks), 1.0)
    shifted = silhouette_iou(verts[None] + [0.3, 0, 0], body.faces, rig, masks)
    assert (shifted < 0.8).all()


def test_lost_frames_by_error_or_iou():
    assert lost_frames([5.0, 150.0, np.nan, 20.0]) == [1]
    iou = np.array([[0.9, 0.8], [0.9, 0.9], [0.1, 0.2], [0.9, 0.9]])
    assert lost_frames([5.0, 150.0, 10.0, 20.0], iou) == [1, 2]
