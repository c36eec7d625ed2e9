"""An independent check of a tracker on a real recording with no 3D ground truth: the tracked
body against keypoints the silhouette trackers never saw, and against the masks.

* :func:`offset_reprojection` - the reprojection error of the body's landmarks against the
  confident detections, raw and after subtracting one constant world offset per landmark
  (keypoint-to-joint offset: where OpenPose puts a hip or shoulder is not where the body
  model's joint is). The offsets are fitted once per run as the median over frames of
  (per-frame triangulation - landmark) and reported.
* :func:`silhouette_iou` - IoU of the rasterised body with the masks, per frame and view.
* :func:`lost_frames` - frames whose median reprojection error (offsets removed) exceeds a
  bound, or whose mean silhouette IoU falls below one.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocap.cameras import Rig, project
from mocap.data.sequence import Detections
from mocap.eval.keypoint_metrics import triangulate_detections
from mocap.render import rasterize_silhouettes


def _residuals(rig: Rig, X: np.ndarray, names: Sequence[str], det: Detections, min_confidence: float):
    """Per detection of a landmark in ``names`` (confidence >= min_confidence, frame < F):
    (error px (N,), frame (N,), view (N,))."""
    index = {n: i for i, n in enumerate(names)}
    to_lm = np.array([index.get(n, -1) for n in det.labels] + [-1])
    lm = to_lm[np.where(det.label >= 0, det.label, len(det.labels))]
    keep = (lm >= 0) & (det.frame < len(X)) & (det.confidence >= min_confidence)
    f, c, lm, xy = det.frame[keep], det.view[keep], lm[keep], det.xy[keep]
    px = project(rig, X)                                                   # (F, C, L, 2)
    err = np.linalg.norm(px[f, c, lm] - xy, axis=1)
    ok = np.isfinite(err)
    return err[ok], f[ok], c[ok]


def fit_offsets(rig: Rig, X: np.ndarray, names: Sequence[str], det: Detections,
                min_confidence: float = 0.5) -> np.ndarray:
    """(L, 3) constant world offsets keypoint - landmark: per landmark, the median over frames
    of (per-frame triangulation of the keypoint - the landmark ``X`` (F, L, 3))."""
    T = triangulate_detections(rig, det, names, len(X), min_confidence)
    d = T - X
    offsets = np.zeros((len(names), 3))
    for i in range(len(names)):
        ok = np.all(np.isfinite(d[:, i]), axis=1)
        if ok.any():
            offsets[i] = np.median(d[ok, i], axis=0)
    return offsets


def offset_reprojection(rig: Rig, X: np.ndarray, names: Sequence[str], det: Detections,
                        min_confidence: float = 0.5, px_scale: float = 1.0,
                        offsets: np.ndarray | None = None) -> dict:
    """Reprojection of landmarks ``X`` (F, L, 3) world metres against ``det``.

    px_scale: multiplies pixel errors (e.g. 1 / image scale to report full-resolution px).
    offsets: (L, 3) keypoint-to-landmark offsets to apply (None: fitted on ``X`` itself by
    :func:`fit_offsets`, which also absorbs a tracker's own constant bias).
    Keys: median_px, median_px_per_view (raw); fitted_median_px, fitted_median_px_per_view,
    fitted_per_frame_px (F,), offsets_mm {landmark: |offset|}, offsets_m {landmark: [x, y, z]}.
    """
    F = len(X)
    if offsets is None:
        offsets = fit_offsets(rig, X, names, det, min_confidence)
    out: dict = {}
    for key, Y in (("", X), ("fitted_", X + offsets[None])):
        err, f, c = _residuals(rig, Y, names, det, min_confidence)
        err = err * px_scale
        out[f"{key}median_px"] = float(np.median(err)) if len(err) else float("nan")
        out[f"{key}median_px_per_view"] = {rig.names[v]: float(np.median(err[c == v])) if np.any(c == v)
                                           else float("nan") for v in range(len(rig))}
        if key:
            out["fitted_per_frame_px"] = [float(np.median(err[f == t])) if np.any(f == t) else float("nan")
                                          for t in range(F)]
    out["offsets_mm"] = {n: float(1e3 * np.linalg.norm(o)) for n, o in zip(names, offsets, strict=True)}
    out["offsets_m"] = {n: o.tolist() for n, o in zip(names, offsets, strict=True)}
    out["keypoints_used"] = int(len(_residuals(rig, X, names, det, min_confidence)[0]))
    return out


def silhouette_iou(vertices: np.ndarray, faces: np.ndarray, rig: Rig, masks: np.ndarray) -> np.ndarray:
    """(F, C) IoU of the body ``vertices`` (F, V, 3) world metres, rasterised with the project's
    rasterizer, against ``masks`` (F, C, H, W) bool."""
    F, C, H, W = masks.shape
    out = np.zeros((F, C))
    for t in range(F):
        px, depth = project(rig, vertices[t], return_depth=True)
        sil = rasterize_silhouettes(px, faces, H, W, depth, near=0.05)
        inter = (sil & masks[t]).sum(axis=(1, 2))
        union = (sil | masks[t]).sum(axis=(1, 2))
        out[t] = np.where(union > 0, inter / np.maximum(union, 1), 1.0)
    return out


def lost_frames(per_frame_px: Sequence[float], iou: np.ndarray | None = None, max_px: float = 100.0,
                min_iou: float = 0.3) -> list[int]:
    """Frames whose (offset-corrected) median reprojection error exceeds ``max_px`` or whose
    mean silhouette IoU over views is below ``min_iou``."""
    bad = {t for t, e in enumerate(per_frame_px) if np.isfinite(e) and e > max_px}
    if iou is not None:
        bad |= {int(t) for t in np.flatnonzero(iou.mean(axis=1) < min_iou)}
    return sorted(bad)
