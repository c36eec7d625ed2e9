"""Person masks from the detector's soft segmentation combined with the silhouette pipeline of
:mod:`mocap.video.segmentation`: GrabCut seeded by the detector's probability and keypoints,
an optional background model, multi-view carving and clean-up.

    masks = combine_masks(images, prob, kps, rig, grabcut=True, background="masked_median",
                          multiview=True)                         # (F, C, H, W) bool

Inputs: images (F, C, H, W, 3) uint8 RGB, prob (F, C, H, W) float person probability from
:class:`mocap.video.detector.PoseDetector` (resized to the images), kps[f][c]: {landmark name:
(2,) pixel} of the subject (:func:`mocap.video.segmentation.keypoint_dict`).

GrabCut labels (per image, in the person's box grown by ``band`` x its size): sure foreground
where prob >= ``sure_fg`` and on the keypoint skeleton; probable foreground where prob >= 0.5
(or where the background model sees change, inside the band); probable background elsewhere
in the band; sure background outside it and, with a background model, where the pixel
matches the known background (colour distance < ``sure_threshold``) and prob < 0.5. GrabCut's
colour models then move the detector's soft edge onto the image's edges.
"""

from __future__ import annotations

from collections.abc import Sequence as Seq

import cv2
import numpy as np

from mocap.cameras import Rig
from mocap.video.segmentation import (
    carve_views,
    clean_mask,
    colour_distance,
    masked_median_background,
    skeleton_mask,
    subject_box,
    subject_region,
)

BACKGROUNDS = ("none", "masked_median")


def _disc(r: int) -> np.ndarray:
    r = max(1, int(r))
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def detector_grabcut(image: np.ndarray, prob: np.ndarray, kp: dict[str, np.ndarray],
                     changed: np.ndarray | None = None, sure_background: np.ndarray | None = None,
                     sure_fg: float = 0.9, band: float = 0.06, iterations: int = 3) -> np.ndarray:
    """(H, W) bool: GrabCut of ``image`` (H, W, 3) RGB seeded by ``prob`` (H, W) and the
    skeleton of ``kp`` (see the module's docstring). changed / sure_background: (H, W) bool
    from a background model (None: not used)."""
    H, W = prob.shape
    fg = prob >= 0.5
    if not fg.any():
        return fg
    ys, xs = np.nonzero(fg)
    size = float(max(np.ptp(ys), np.ptp(xs), 8))
    region = cv2.dilate(fg.astype(np.uint8), _disc(round(band * size))).astype(bool)
    gc = np.full((H, W), cv2.GC_BGD, np.uint8)
    gc[region] = cv2.GC_PR_BGD
    gc[region & fg] = cv2.GC_PR_FGD
    if changed is not None:
        gc[region & changed & ~fg] = cv2.GC_PR_FGD
    if sure_background is not None:
        gc[region & sure_background & ~fg] = cv2.GC_BGD
    sure = prob >= sure_fg
    sure = cv2.erode(sure.astype(np.uint8), _disc(max(1, round(0.01 * size)))).astype(bool)
    if len(kp) >= 3:
        sure |= skeleton_mask(kp, (H, W), max(1, round(0.01 * size))) & fg
    gc[sure] = cv2.GC_FGD
    ys, xs = np.nonzero(region)
    pad = max(8, round(0.08 * size))
    x0, y0, x1, y1 = max(0, xs.min() - pad), max(0, ys.min() - pad), min(W, xs.max() + pad + 1), \
        min(H, ys.max() + pad + 1)
    crop = np.ascontiguousarray(gc[y0:y1, x0:x1])
    if not ((crop == cv2.GC_FGD) | (crop == cv2.GC_PR_FGD)).any():
        return fg
    if not ((crop == cv2.GC_BGD) | (crop == cv2.GC_PR_BGD)).any():
        crop[0, :] = cv2.GC_BGD
    bgd, fgd = np.zeros((1, 65)), np.zeros((1, 65))
    cv2.grabCut(np.ascontiguousarray(image[y0:y1, x0:x1, ::-1]), crop, None, bgd, fgd, iterations,
                cv2.GC_INIT_WITH_MASK)
    out = np.zeros((H, W), bool)
    out[y0:y1, x0:x1] = (crop == cv2.GC_FGD) | (crop == cv2.GC_PR_FGD)
    return out


def combine_masks(images: np.ndarray, prob: np.ndarray, kps: Seq[Seq[dict[str, np.ndarray]]],
                  rig: Rig | None = None, grabcut: bool = True, background: str = "none",
                  multiview: bool = False, threshold: float = 30.0, sure_threshold: float = 8.0,
                  min_seen: float = 0.2, sure_fg: float = 0.9, band: float = 0.06, iterations: int = 3,
                  voxel: float = 0.025, carve_tolerance: int = 0, kernel: int = 3) -> np.ndarray:
    """(F, C, H, W) bool person masks (see the module's docstring). background: ``none`` or
    ``masked_median`` (per view, the median of the frames away from the subject's skeleton;
    needs several frames); multiview: carve with the visual hull (needs ``rig`` and keypoints
    in >= 2 views)."""
    images, prob = np.asarray(images), np.asarray(prob, np.float32)
    if background not in BACKGROUNDS:
        raise ValueError(f"unknown background {background!r} for combine_masks "
                         f"(known: {', '.join(BACKGROUNDS)})")
    if prob.shape != images.shape[:4]:
        raise ValueError(f"detector probabilities are {prob.shape}, the images {images.shape[:4]} "
                         "(F, C, H, W): same frames and size needed")
    if multiview and rig is None:
        raise ValueError("combine_masks(multiview=True) needs the rig")
    F, C, H, W = prob.shape
    changed = sure_bg = None
    if background == "masked_median":
        changed, sure_bg = np.zeros((F, C, H, W), bool), np.zeros((F, C, H, W), bool)
        for c in range(C):
            hide = np.stack([subject_region(kps[f][c], (H, W)) | (prob[f, c] >= 0.1) for f in range(F)])
            bg, _ = masked_median_background(images[:, c], hide)
            known = (~hide).sum(0) >= max(3, min_seen * F)
            for f in range(F):
                d = colour_distance(images[f, c], bg)
                changed[f, c] = (d > threshold) | ~known
                sure_bg[f, c] = (d < sure_threshold) & known
    masks = np.zeros((F, C, H, W), bool)
    for f in range(F):
        for c in range(C):
            kp = kps[f][c]
            if grabcut:
                raw = detector_grabcut(images[f, c], prob[f, c], kp,
                                       None if changed is None else changed[f, c],
                                       None if sure_bg is None else sure_bg[f, c], sure_fg, band, iterations)
            else:
                raw = prob[f, c] >= 0.5
            anchor = skeleton_mask(kp, (H, W), 1) if len(kp) >= 3 else None
            masks[f, c] = clean_mask(raw, anchor, kernel)
        if multiview:
            box3 = subject_box(rig, kps[f])
            if box3 is not None:
                carved = carve_views(masks[f], rig, box3, voxel, carve_tolerance)
                masks[f] = np.stack([clean_mask(carved[c], skeleton_mask(kps[f][c], (H, W), 1)
                                                if len(kps[f][c]) >= 3 else None, kernel) for c in range(C)])
    return masks
