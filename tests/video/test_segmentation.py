"""The segmentation stage on a synthetic video with known masks: our renderer's textured body
composited over a textured background."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from mocap.body.landmarks import LandmarkSet
from mocap.cameras import project, ring_rig
from mocap.data.generate import subject_shape
from mocap.data.motion import generate_motion
from mocap.data.sequence import Detections, Sequence
from mocap.video.segmentation import (
    carve_views,
    clean_mask,
    fill_holes,
    iou,
    keypoint_dict,
    masked_median_background,
    segment_sequence,
    subject_box,
)

F = 6


def textured_background(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """(H, W, 3) uint8: smooth colour blobs plus fine noise and a few stripes."""
    low = rng.integers(0, 256, (6, 8, 3)).astype(np.float32)
    img = cv2.resize(low, (w, h), interpolation=cv2.INTER_CUBIC)
    img += rng.normal(0, 8, (h, w, 3))
    for y in range(0, h, 24):
        img[y:y + 3] = rng.integers(0, 256, 3)
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def video(body):
    """A synthetic recording: images, true masks (GL coverage), keypoints, background clip."""
    from mocap.render.pyrender_rgb import RenderMesh, RGBRenderer, body_texture

    rig = ring_rig(4, 3.5, 1.5, 240, 320, fov_deg=55)
    W, H = 240, 320
    chi = generate_motion(body, "walk", F, fps=25, seed=3)
    shaped = body.shaped(subject_shape(body, 3, 0.8))
    rng = np.random.default_rng(0)
    backgrounds = np.stack([textured_background(rng, H, W) for _ in range(len(rig))])
    texture = body_texture(body.part_labels, body.joint_names, seed=3)
    lm = LandmarkSet(body)
    rest = lm.rest_points(shaped)
    images = np.zeros((F, len(rig), H, W, 3), np.uint8)
    truth = np.zeros((F, len(rig), H, W), bool)
    rows = []
    with RGBRenderer(W, H) as renderer:
        for f in range(F):
            out = shaped.pose(chi[f])
            for c, cam in enumerate(rig):
                colour, depth = renderer.render(cam, [RenderMesh(out.vertices[0], body.faces, texture)])
                truth[f, c] = depth > 0
                noise = rng.normal(0, 2, (H, W, 3))
                images[f, c] = np.clip(np.where(truth[f, c][..., None], colour, backgrounds[c]) + noise,
                                       0, 255).astype(np.uint8)
            px = project(rig, lm.from_transforms(out.transforms, rest)[0])
            rows += [(f, c, k, *px[c, k], 1.0) for c in range(len(rig)) for k in range(len(lm))]
    arr = np.array(rows, np.float64)
    det = Detections(lm.names, arr[:, 0].astype(int), arr[:, 1].astype(int), arr[:, 2].astype(int),
                     arr[:, 3:5], arr[:, 5])
    clip = np.clip(backgrounds[None] + rng.normal(0, 2, (5,) + backgrounds.shape), 0, 255).astype(np.uint8)
    seq = Sequence(name="synthetic_video", rig=rig, fps=25, images=images, detections=det)
    return seq, truth, clip


def mean_iou(masks, truth) -> float:
    return float(np.mean([iou(m, t) for m, t in zip(masks.reshape(-1, *masks.shape[2:]),
                                                      truth.reshape(-1, *truth.shape[2:]), strict=True)]))


def test_keypoint_guided_segmentation_reaches_095_iou_and_unguided_is_reported(video):
    seq, truth, clip = video
    guided = segment_sequence(seq, method="keypoint_grabcut", background="median", background_clip=clip,
                              multiview=True)
    score = mean_iou(guided.masks, truth)
    plain = segment_sequence(seq, method="keypoint_grabcut", background="median", background_clip=clip,
                             keypoints=False)
    unguided = mean_iou(plain.masks, truth)
    print(f"\nsynthetic video IoU: keypoint-guided GrabCut + carving {score:.3f}, "
          f"without keypoints (median background model + clean-up) {unguided:.3f}")
    assert guided.info["keypoints"] and guided.info["multiview"]
    assert not plain.info["keypoints"] and plain.info["method"] == "median"
    assert score >= 0.95
    assert 0.5 < unguided <= score + 0.02


def test_without_a_clip_the_masked_median_beats_the_plain_median(video):
    seq, truth, _ = video
    masked = segment_sequence(seq, method="keypoint_grabcut", background="masked_median")
    plain = segment_sequence(seq, method="keypoint_grabcut", background="median")
    assert masked.info["background_source"] == "frames"
    a, b = mean_iou(masked.masks, truth), mean_iou(plain.masks, truth)
    print(f"\nno clip, {F} frames: masked median {a:.3f}, plain median {b:.3f}")
    assert a > b


def test_missing_background_clip_is_an_error_when_the_method_needs_it(video):
    seq, _, clip = video
    with pytest.raises(ValueError, match="needs a background clip"):
        segment_sequence(seq, method="median", background_source="clip")
    with pytest.raises(ValueError, match="background clip is"):
        segment_sequence(seq, method="median", background_clip=clip[:, :, :100])
    with pytest.raises(ValueError, match="unknown segmentation method"):
        segment_sequence(seq, method="deep")


def test_carving_removes_a_blob_no_other_view_confirms(video):
    seq, truth, _ = video
    f = 2
    masks = truth[f].copy()
    masks[0, 10:60, 10:60] = True                     # a ghost in view 0 only (not on the body)
    kps = [keypoint_dict(seq.detections.select(f, c)) for c in range(seq.num_views)]
    box = subject_box(seq.rig, kps)
    out = carve_views(masks, seq.rig, box, voxel=0.02)
    assert not out[0, 10:60, 10:60].any()
    for c in range(seq.num_views):
        assert iou(out[c], truth[f, c]) > 0.97


def test_masked_median_sees_through_a_subject_that_moves_away():
    frames = np.zeros((5, 4, 4, 3), np.uint8)
    frames[:] = 100
    frames[:3, 1, 1] = 250                            # the subject covers (1, 1) in 3 of 5 frames
    hide = frames[..., 0] == 250
    bg, seen = masked_median_background(frames, hide)
    assert bg[1, 1, 0] == 100 and seen.all()
    assert np.median(frames, axis=0)[1, 1, 0] == 250  # the plain median keeps the ghost


def test_clean_mask_keeps_the_anchored_component_and_fills_holes():
    m = np.zeros((40, 40), bool)
    m[5:35, 5:20] = True
    m[15:20, 10:14] = False                           # a hole
    m[5:38, 25:39] = True                             # a bigger component elsewhere
    anchor = np.zeros_like(m)
    anchor[10, 10] = True
    out = clean_mask(m, anchor)
    assert out[17, 12] and not out[20, 30]
    assert clean_mask(m)[20, 30]                      # no anchor: the largest
    ring = np.zeros((9, 9), bool)
    ring[2:7, 2:7] = True
    ring[4, 4] = False
    assert fill_holes(ring)[4, 4]
