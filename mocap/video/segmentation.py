"""Silhouettes from real video: background models, keypoint-guided GrabCut, multi-view carving
and morphological clean-up.

    result = segment_sequence(seq, method="keypoint_grabcut", multiview=True)
    result.masks      # (F, C, H, W) bool
    result.info       # method, settings, seconds per frame per view

Stages (each a pure function on arrays, used by :func:`segment_sequence`):

1. :func:`background_foreground` - a per-pixel background model: ``median`` (colour distance
   to the per-pixel median of a background clip, or of the sequence's own frames), or
   OpenCV's ``mog2`` / ``knn`` subtractors (trained on the clip or on the frames, then applied
   with learning rate 0; shadows count as background).
2. :func:`keypoint_grabcut` - the subject's skeleton drawn from its detected keypoints (limb
   widths scaled by the person's size) is sure foreground, everything farther than a
   body-shaped reach from the skeleton sure background, the background model's answer in
   between "probable" (sure background only where the background is known: a masked-median
   pixel seen away from the subject in enough frames); GrabCut settles the rest. The detections of a
   :class:`Sequence` loaded with ``person="subject"`` are the subject's only, so the
   experimenter in the background falls outside the reach or outside the skeleton's component.
3. :func:`carve_views` - multi-view consistency: voxels of the subject's 3D box (from the
   triangulated keypoints) survive where they project into the foreground of every view (of
   all but ``tolerance`` views); each view keeps only the pixels covered by surviving voxels.
4. :func:`clean_mask` - opening / closing, holes filled, and the connected component(s) that
   hold the subject's skeleton (the largest one when there are no keypoints).

Methods (``method=``): ``median``, ``mog2``, ``knn`` (a background model + clean-up) and
``keypoint_grabcut`` (with the background model named by ``background``), each optionally
followed by ``multiview`` carving. ``background_source="clip"`` needs ``background_clip``
(images (B, C, H, W, 3) or a folder of videos); ``"frames"`` models the background from the
sequence itself; ``"auto"`` uses the clip when given.

No person-segmentation network is used: of the packages on the index that ship weights
inside the wheel, only the legacy MediaPipe releases (0.10.x, ``selfie_segmentation.tflite``)
qualify, and they need numpy < 2 and protobuf < 5.
"""

from __future__ import annotations

import time
from collections.abc import Sequence as Seq
from dataclasses import dataclass, field

import cv2
import numpy as np

from mocap.cameras import Rig, project, triangulate
from mocap.data.sequence import Detections, Sequence

#: limb segments drawn as sure foreground, by landmark name (OpenPose and mocap names)
SKELETON = (("l_shoulder", "l_elbow"), ("l_elbow", "l_wrist"), ("r_shoulder", "r_elbow"),
            ("r_elbow", "r_wrist"), ("l_hip", "l_knee"), ("l_knee", "l_ankle"), ("r_hip", "r_knee"),
            ("r_knee", "r_ankle"), ("l_ankle", "l_heel"), ("l_ankle", "l_toe"), ("l_heel", "l_toe"),
            ("r_ankle", "r_heel"), ("r_ankle", "r_toe"), ("r_heel", "r_toe"), ("neck", "head_top"),
            ("neck", "nose"), ("thorax", "head"), ("head", "head_top"), ("pelvis", "thorax"),
            ("l_shoulder", "r_shoulder"), ("l_hip", "r_hip"))
TORSO = ("l_shoulder", "r_shoulder", "r_hip", "l_hip")
METHODS = ("median", "mog2", "knn", "keypoint_grabcut")
BACKGROUNDS = ("median", "masked_median", "mog2", "knn", "none")


@dataclass(frozen=True)
class SegmentationResult:
    masks: np.ndarray            # (F, C, H, W) bool
    info: dict = field(default_factory=dict)


# --- 1. background models ---------------------------------------------------------------------

def median_background(frames: np.ndarray) -> np.ndarray:
    """(H, W, 3) per-pixel median of ``frames`` (N, H, W, 3)."""
    return np.median(np.asarray(frames), axis=0).astype(np.uint8)


def masked_median_background(frames: np.ndarray, hide: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel median of ``frames`` (N, H, W, 3) over the frames where ``hide`` (N, H, W) is
    False (e.g. away from the subject's skeleton): (background (H, W, 3) uint8, seen (H, W)
    bool). Pixels hidden in every frame fall back to the plain median and ``seen`` False."""
    frames = np.asarray(frames)
    x = frames.astype(np.float32)
    x[hide] = np.nan
    seen = ~hide.all(axis=0)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            bg = np.nanmedian(x, axis=0)
    plain = np.median(frames, axis=0)
    bg = np.where(seen[..., None], bg, plain)
    return np.round(bg).astype(np.uint8), seen


def colour_distance(img: np.ndarray, background: np.ndarray) -> np.ndarray:
    """(H, W) float32 largest per-channel absolute difference."""
    return np.abs(img.astype(np.int16) - background.astype(np.int16)).max(axis=-1).astype(np.float32)


def background_foreground(frames: np.ndarray, method: str = "median",
                          training: np.ndarray | None = None, threshold: float = 30.0) -> np.ndarray:
    """(N, H, W) bool raw foreground of ``frames`` (N, H, W, 3) RGB of one view.

    training: (B, H, W, 3) frames of the empty background (None: ``frames`` themselves).
    threshold: colour distance (``median``) or OpenCV's varThreshold / dist2Threshold scale.
    """
    frames = np.asarray(frames)
    train = frames if training is None else np.asarray(training)
    if method == "median":
        bg = median_background(train)
        return np.stack([colour_distance(im, bg) > threshold for im in frames])
    if method in ("mog2", "knn"):
        sub = (cv2.createBackgroundSubtractorMOG2(history=len(train), varThreshold=threshold / 2,
                                                  detectShadows=True) if method == "mog2" else
               cv2.createBackgroundSubtractorKNN(history=len(train), dist2Threshold=threshold * 10,
                                                 detectShadows=True))
        for im in train:
            sub.apply(im[..., ::-1])
        return np.stack([sub.apply(im[..., ::-1], learningRate=0) == 255 for im in frames])
    raise ValueError(f"unknown background model {method!r} (known: median, mog2, knn)")


# --- 2. keypoint guidance ---------------------------------------------------------------------

def keypoint_dict(det: Detections | None, min_confidence: float = 0.3) -> dict[str, np.ndarray]:
    """{name: (2,) pixel} of one frame and view's detections above ``min_confidence``."""
    if det is None:
        return {}
    out = {}
    for lab, xy, conf in zip(det.label, det.xy, det.confidence, strict=True):
        if lab >= 0 and conf >= min_confidence:
            out.setdefault(det.labels[lab], xy)
    return out


def skeleton_mask(kp: dict[str, np.ndarray], shape: tuple[int, int], thickness: int) -> np.ndarray:
    """(H, W) bool: limb segments and the torso polygon of keypoints ``kp``."""
    m = np.zeros(shape, np.uint8)
    for a, b in SKELETON:
        if a in kp and b in kp:
            cv2.line(m, tuple(np.round(kp[a]).astype(int)), tuple(np.round(kp[b]).astype(int)), 1,
                     thickness)
    if all(n in kp for n in TORSO):
        cv2.fillConvexPoly(m, np.round([kp[n] for n in TORSO]).astype(np.int32), 1)
    for p in kp.values():
        cv2.circle(m, tuple(np.round(p).astype(int)), max(1, thickness // 2), 1, -1)
    return m.astype(bool)


def keypoint_box(kp: dict[str, np.ndarray], shape: tuple[int, int],
                 margin: float) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) box of the keypoints grown by ``margin`` x its height, clipped."""
    pts = np.array(list(kp.values()))
    (x0, y0), (x1, y1) = pts.min(0), pts.max(0)
    grow = margin * max(y1 - y0, x1 - x0, 1.0)
    H, W = shape
    return (int(max(0, x0 - grow)), int(max(0, y0 - 1.5 * grow)), int(min(W, x1 + grow + 1)),
            int(min(H, y1 + grow + 1)))


def person_size(kp: dict[str, np.ndarray]) -> float:
    """The person's size in pixels: the larger extent of its keypoints (about its height)."""
    pts = np.array(list(kp.values()))
    return float(max(np.ptp(pts[:, 1]), np.ptp(pts[:, 0]), 1.0))


def body_region(kp: dict[str, np.ndarray], shape: tuple[int, int], fraction: float) -> np.ndarray:
    """(H, W) bool: the skeleton with limbs ``fraction`` x the person's size thick, and a head
    disc of half that radius: a body-shaped region that scales with the person."""
    size = person_size(kp)
    m = skeleton_mask(kp, shape, max(1, round(fraction * size))).view(np.uint8)
    for name in ("head_top", "nose", "head"):
        if name in kp:
            cv2.circle(m, tuple(np.round(kp[name]).astype(int)), max(1, round(0.8 * fraction * size)), 1, -1)
    return m.view(bool)


def keypoint_grabcut(image: np.ndarray, kp: dict[str, np.ndarray], prior: np.ndarray | None,
                     reach: float = 0.35, limb_fraction: float = 0.015,
                     iterations: int = 4, sure_background: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool silhouette of the person with keypoints ``kp`` in ``image`` (H, W, 3) RGB.

    Sizes scale with the person (:func:`person_size` of its keypoints, about its height):
    sure foreground is the skeleton with limbs ``limb_fraction`` x size thick (the torso
    polygon, a head disc); everything farther than ``reach`` x size from the skeleton is sure
    background (the experimenter, ghosts elsewhere); in between, probable foreground where
    ``prior`` (H, W) bool (the background model's foreground) says so, else probable
    background, or sure background where ``sure_background`` (H, W) bool says so (off the
    skeleton). prior None: a skeleton 3 x ``limb_fraction`` thick stands in.
    """
    H, W = image.shape[:2]
    if len(kp) < 3:
        return np.zeros((H, W), bool) if prior is None else prior.copy()
    sure = body_region(kp, (H, W), limb_fraction)
    region = body_region(kp, (H, W), reach)
    if prior is None:
        prior = body_region(kp, (H, W), 3 * limb_fraction)
    gc = np.full((H, W), cv2.GC_BGD, np.uint8)
    gc[region] = np.where(prior[region], cv2.GC_PR_FGD, cv2.GC_PR_BGD)
    if sure_background is not None:
        gc[region & sure_background] = cv2.GC_BGD
    gc[sure] = cv2.GC_FGD
    ys, xs = np.nonzero(region)
    pad = max(8, round(0.08 * person_size(kp)))  # GrabCut's background model sees the surround
    cx0, cy0, cx1, cy1 = max(0, xs.min() - pad), max(0, ys.min() - pad), min(W, xs.max() + pad + 1), \
        min(H, ys.max() + pad + 1)
    crop = np.ascontiguousarray(gc[cy0:cy1, cx0:cx1])
    if not ((crop == cv2.GC_BGD) | (crop == cv2.GC_PR_BGD)).any():
        crop[0, :] = cv2.GC_BGD
    bgd, fgd = np.zeros((1, 65)), np.zeros((1, 65))
    cv2.grabCut(np.ascontiguousarray(image[cy0:cy1, cx0:cx1, ::-1]), crop, None, bgd, fgd,
                iterations, cv2.GC_INIT_WITH_MASK)
    out = np.zeros((H, W), bool)
    out[cy0:cy1, cx0:cx1] = (crop == cv2.GC_FGD) | (crop == cv2.GC_PR_FGD)
    return out


# --- 3. multi-view carving --------------------------------------------------------------------

def subject_box(rig: Rig, kps: Seq[dict[str, np.ndarray]], margin: float = 0.25) -> np.ndarray | None:
    """(3, 2) world box (metres) around the triangulated keypoints of one frame (None: too few)."""
    names = sorted(set().union(*(k.keys() for k in kps)))
    xy = np.zeros((len(rig), len(names), 2))
    ok = np.zeros((len(rig), len(names)), bool)
    for c, kp in enumerate(kps):
        for i, n in enumerate(names):
            if n in kp:
                xy[c, i], ok[c, i] = kp[n], True
    if len(names) < 3:
        return None
    X = triangulate(rig, xy, valid=ok)
    X = X[np.all(np.isfinite(X), axis=1) & (ok.sum(0) >= 2)]
    if len(X) < 3:
        return None
    lo, hi = np.percentile(X, 2, axis=0), np.percentile(X, 98, axis=0)
    return np.stack([lo - margin, hi + margin], axis=1)


def carve_views(masks: np.ndarray, rig: Rig, box: np.ndarray, voxel: float = 0.025,
                tolerance: int = 0) -> np.ndarray:
    """(C, H, W) bool: ``masks`` (C, H, W) restricted to pixels covered by the visual hull.

    box: (3, 2) world box; a voxel centre survives when it falls in the foreground (or outside
    the image, where a view has no say) of at least C - ``tolerance`` views.
    """
    C, H, W = masks.shape
    axes = [np.arange(lo + voxel / 2, hi, voxel) for lo, hi in box]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    px, depth = project(rig, pts, return_depth=True)                   # (C, N, 2), (C, N)
    u, v = np.round(px[..., 0]).astype(np.int64), np.round(px[..., 1]).astype(np.int64)
    inimg = (depth > 0) & (u >= 0) & (u < W) & (v >= 0) & (v < H)
    votes = np.zeros(len(pts), np.int64)
    for c in range(C):
        hit = np.ones(len(pts), bool)
        i = inimg[c]
        hit[i] = masks[c, v[c, i], u[c, i]]
        votes += hit
    keep = votes >= C - tolerance
    out = np.zeros_like(masks)
    for c in range(C):
        k = keep & inimg[c]
        hull = np.zeros((H, W), np.uint8)
        hull[v[c, k], u[c, k]] = 1
        z = max(float(np.median(depth[c, k])) if k.any() else 1.0, 1e-3)
        r = max(1, int(np.ceil(rig.K[c, 0, 0] * voxel / z)))      # a voxel's size in pixels
        hull = cv2.dilate(hull, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
        out[c] = masks[c] & hull.astype(bool)
    return out


# --- 4. clean-up ------------------------------------------------------------------------------

def fill_holes(mask: np.ndarray) -> np.ndarray:
    m = np.pad(mask.astype(np.uint8), 1)
    flood = m.copy()
    cv2.floodFill(flood, np.zeros((m.shape[0] + 2, m.shape[1] + 2), np.uint8), (0, 0), 1)
    return (m | (1 - flood)).astype(bool)[1:-1, 1:-1]


def clean_mask(mask: np.ndarray, anchor: np.ndarray | None = None, kernel: int = 3,
               min_fraction: float = 0.05) -> np.ndarray:
    """Opening then closing with a ``kernel`` ellipse, holes filled, and the connected
    components that touch ``anchor`` (H, W) bool (e.g. the skeleton) and hold at least
    ``min_fraction`` of the largest one's area; without an anchor (or when none touches it)
    the largest component."""
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (kernel, kernel))
    m = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, k)
    m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, k)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
    if n <= 1:
        return m.astype(bool)
    keep = np.zeros(n, bool)
    if anchor is not None and anchor.any():
        touched = np.bincount(labels[anchor], minlength=n)
        touched[0] = 0
        big = stats[:, cv2.CC_STAT_AREA] >= min_fraction * stats[1:, cv2.CC_STAT_AREA].max()
        keep = (touched > 0) & big
    if not keep.any():
        keep[1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))] = True
    keep[0] = False
    return fill_holes(keep[labels])


# --- the stage ------------------------------------------------------------------------------

def subject_region(kp: dict[str, np.ndarray], shape: tuple[int, int], fraction: float = 0.12) -> np.ndarray:
    """(H, W) bool: a generous region around the subject's skeleton (limbs drawn ``fraction``
    of the person's height thick), hidden from the masked median background."""
    if len(kp) < 3:
        return np.zeros(shape, bool)
    pts = np.array(list(kp.values()))
    height = max(np.ptp(pts[:, 1]), np.ptp(pts[:, 0]), 1.0)
    m = skeleton_mask(kp, shape, max(2, round(fraction * height))).astype(np.uint8)
    for name in ("head_top", "nose", "head"):
        if name in kp:
            cv2.circle(m, tuple(np.round(kp[name]).astype(int)), max(2, round(0.09 * height)), 1, -1)
    return m.astype(bool)


def segment_sequence(seq: Sequence, method: str = "keypoint_grabcut", background: str = "masked_median",
                     background_source: str = "auto", background_clip: np.ndarray | None = None,
                     threshold: float = 30.0, sure_threshold: float = 5.0, keypoints: bool = True,
                     min_confidence: float = 0.3, multiview: bool = False, voxel: float = 0.025,
                     carve_tolerance: int = 0, reach: float | None = None, limb_fraction: float = 0.015,
                     min_seen: float = 0.2, iterations: int = 4, kernel: int = 3) -> SegmentationResult:
    """Masks (F, C, H, W) for ``seq``'s images (at the sequence's resolution).

    method: ``median`` / ``mog2`` / ``knn`` (background model only) or ``keypoint_grabcut``
    (``background`` model + the subject's keypoints + GrabCut). ``background`` for GrabCut:
    ``median``, ``masked_median`` (the median over frames where the pixel is away from the
    subject's skeleton: no ghost of a subject that barely moves), ``mog2``, ``knn`` or
    ``none``. Colour distance above ``threshold`` is probable foreground, below
    ``sure_threshold`` sure background (median models), but only where the background is
    known: a masked-median pixel seen (away from the subject) in fewer than ``min_seen`` x
    frames (at least 3) has no reliable background and is probable foreground near the
    subject. reach / limb_fraction: see :func:`keypoint_grabcut` (fractions of the person's
    size); reach None: 0.35 with a background model, 0.2 without one (``background='none'``:
    with no background evidence the body-shaped region is what keeps the surround out).
    keypoints=False drops the guidance
    (skeleton, box, GrabCut) even when detections exist. multiview: carve with the visual hull
    of the subject's 3D box (needs keypoints in >= 2 views).
    background_clip: (B, C, H, W, 3) RGB frames of the empty scene at the same resolution.
    """
    if method not in METHODS:
        raise ValueError(f"unknown segmentation method {method!r} (known: {', '.join(METHODS)})")
    if seq.images is None:
        raise ValueError(f"sequence {seq.name!r} has no images to segment")
    if background_source not in ("auto", "clip", "frames"):
        raise ValueError(f"background_source must be auto, clip or frames, got {background_source!r}")
    if background_source == "clip" and background_clip is None:
        raise ValueError(f"segmentation with background_source='clip' needs a background clip "
                         f"(background_clip=...), none given for {seq.name!r}")
    use_clip = background_clip is not None and background_source != "frames"
    F, C = seq.num_frames, seq.num_views
    W, H = seq.image_size
    if use_clip and np.asarray(background_clip).shape[1:] != (C, H, W, 3):
        raise ValueError(f"background clip is {np.asarray(background_clip).shape[1:]}, the sequence's "
                         f"images are {(C, H, W, 3)} (same views and resolution needed)")
    guided = keypoints and seq.detections is not None and len(seq.detections) > 0
    bg_model = method if method != "keypoint_grabcut" else background
    if bg_model == "masked_median" and not guided and not use_clip:
        bg_model = "median"
    if method == "keypoint_grabcut" and not guided:
        method_run = bg_model if bg_model in ("median", "mog2", "knn") else "median"
    else:
        method_run = method
    if reach is None:
        reach = 0.2 if bg_model == "none" else 0.35
    t0 = time.perf_counter()
    images = np.stack([np.asarray(seq.images[f]) for f in range(F)])          # (F, C, H, W, 3)
    t_read = time.perf_counter() - t0
    t0 = time.perf_counter()
    kps = [[keypoint_dict(seq.detections.select(f, c), min_confidence) if guided else {}
            for c in range(C)] for f in range(F)]
    prior = np.zeros((F, C, H, W), bool)
    sure_bg = None
    if bg_model in ("median", "masked_median"):
        sure_bg = np.zeros((F, C, H, W), bool)
        for c in range(C):
            known = np.ones((H, W), bool)
            if use_clip:
                bg = median_background(np.asarray(background_clip)[:, c])
            elif bg_model == "masked_median":
                hide = np.stack([subject_region(kps[f][c], (H, W)) for f in range(F)])
                bg, _ = masked_median_background(images[:, c], hide)
                known = (~hide).sum(0) >= max(3, min_seen * F)
            else:
                bg = median_background(images[:, c])
            for f in range(F):
                d = colour_distance(images[f, c], bg)
                prior[f, c] = (d > threshold) | ~known
                sure_bg[f, c] = (d < sure_threshold) & known
    elif bg_model in ("mog2", "knn"):
        for c in range(C):
            train = np.asarray(background_clip)[:, c] if use_clip else images[:, c]
            prior[:, c] = background_foreground(images[:, c], bg_model, train, threshold)
    elif bg_model != "none":
        raise ValueError(f"unknown background model {bg_model!r}")
    masks = np.zeros((F, C, H, W), bool)
    for f in range(F):
        for c in range(C):
            kp = kps[f][c]
            if method_run == "keypoint_grabcut" and len(kp) >= 3:
                raw = keypoint_grabcut(images[f, c], kp, prior[f, c] if bg_model != "none" else None,
                                       reach, limb_fraction, iterations,
                                       None if sure_bg is None else sure_bg[f, c])
            else:
                raw = prior[f, c]
            anchor = None
            if len(kp) >= 3:
                anchor = skeleton_mask(kp, (H, W), 1)
                raw = raw & body_region(kp, (H, W), reach)
            masks[f, c] = clean_mask(raw, anchor, kernel)
        if multiview and guided:
            box3 = subject_box(seq.rig, kps[f])
            if box3 is not None:
                carved = carve_views(masks[f], seq.rig, box3, voxel, carve_tolerance)
                masks[f] = np.stack([clean_mask(carved[c], skeleton_mask(kps[f][c], (H, W), 1)
                                                if len(kps[f][c]) >= 3 else None, kernel)
                                     for c in range(C)])
    seconds = time.perf_counter() - t0
    info = {"method": method_run, "background": bg_model,
            "background_source": "clip" if use_clip else "frames", "keypoints": bool(guided),
            "multiview": bool(multiview and guided), "threshold": threshold, "reach": reach,
            "resolution": [W, H], "frames": F, "views": C,
            "seconds_per_frame_per_view": seconds / (F * C),
            "decode_seconds_per_frame_per_view": t_read / (F * C)}
    return SegmentationResult(masks, info)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks (1.0 when both are empty)."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    union = np.logical_or(a, b).sum()
    return float(np.logical_and(a, b).sum() / union) if union else 1.0
