"""The colour marker detector of Canton-Ferrer et al. 2010, Sec. 4.2.

Images are converted to YCrCb, where the chrominance (Cr, Cb) of a coloured marker changes
little with shading. The marker colour is learned from one labelled frame: the (Cr, Cb)
values of the pixels around each labelled marker are modelled as a Gaussian (mean, 2x2
covariance). A pixel belongs to a marker when its Mahalanobis distance to that Gaussian is
below a threshold; connected regions of such pixels within an area range are the
detections, at their centroids. The detections are unlabelled (label -1): the tracker's
gating assigns them to landmarks.

:func:`match_detections` scores a detector against ground-truth marker projections: the
detection rate (share of visible markers with a detection within ``radius_px``), the false
positive rate (unmatched detections per visible marker, the paper's definition) and the
pixel error of the matched ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from mocap.data.sequence import Detections


def chroma(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 RGB -> (H, W, 2) float (Cr, Cb) in [0, 255]."""
    ycc = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2YCrCb)
    return ycc[..., 1:].astype(np.float64)


@dataclass(frozen=True)
class ChromaModel:
    """Gaussian of marker chrominance: mean (2,) (Cr, Cb) and covariance (2, 2)."""

    mean: np.ndarray
    cov: np.ndarray

    @staticmethod
    def fit(images: Sequence[np.ndarray], points: Sequence[np.ndarray], radius: int = 1,
            min_variance: float = 4.0, trim: float = 2.5, trim_iterations: int = 3) -> ChromaModel:
        """Learn from labelled images: images[i] (H, W, 3) RGB with marker centres points[i]
        (M_i, 2) pixels; the pixels within ``radius`` (a square window) of each centre are
        samples. Windows also catch pixels of the body or background next to a marker (or a
        label whose marker is hidden), so the Gaussian is refitted ``trim_iterations`` times to
        the samples within Mahalanobis distance ``trim`` of the previous fit (the first one
        around the median). ``min_variance`` (levels^2) keeps the covariance well
        conditioned."""
        samples = []
        for img, pts in zip(images, points, strict=True):
            cc = chroma(img)
            h, w = cc.shape[:2]
            for x, y in np.round(np.asarray(pts, np.float64).reshape(-1, 2)).astype(int):
                y0, y1 = max(0, y - radius), min(h, y + radius + 1)
                x0, x1 = max(0, x - radius), min(w, x + radius + 1)
                if y0 < y1 and x0 < x1:
                    samples.append(cc[y0:y1, x0:x1].reshape(-1, 2))
        if not samples:
            raise ValueError("no labelled marker pixels to learn the colour from")
        s = np.concatenate(samples)
        keep = np.ones(len(s), bool)
        for _ in range(trim_iterations + 1):       # trimmed refits: drop pixels of the body or
            mean = np.median(s[keep], axis=0) if _ == 0 else s[keep].mean(axis=0)   # background
            cov = (np.cov(s[keep].T) if keep.sum() > 2 else np.zeros((2, 2))) + min_variance * np.eye(2)
            d = s - mean
            keep = np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d) < trim**2
            if keep.sum() < 3:
                break
        return ChromaModel(mean, cov)

    def distance(self, image: np.ndarray) -> np.ndarray:
        """(H, W) Mahalanobis distance of every pixel's chrominance to the model."""
        d = chroma(image) - self.mean
        inv = np.linalg.inv(self.cov)
        return np.sqrt(np.einsum("...i,ij,...j->...", d, inv, d))


def detect_markers(image: np.ndarray, model: ChromaModel, threshold: float = 3.0, min_area: int = 2,
                   max_area: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Marker detections in one RGB image (H, W, 3): centroids (N, 2) pixels and areas (N,)
    of the 8-connected regions with Mahalanobis distance < ``threshold`` and an area in
    [min_area, max_area] pixels."""
    mask = (model.distance(image) < threshold).astype(np.uint8)
    n, _, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    area = stats[1:, cv2.CC_STAT_AREA]
    keep = (area >= min_area) & (area <= max_area)
    return centroids[1:][keep].astype(np.float64), area[keep]


def detect_sequence(images: np.ndarray, model: ChromaModel, labels: tuple[str, ...], **options) -> Detections:
    """Unlabelled detections of every frame and view of images (F, C, H, W, 3)."""
    rows = []
    for f in range(images.shape[0]):
        for c in range(images.shape[1]):
            xy, area = detect_markers(images[f, c], model, **options)
            rows += [(f, c, x, y) for x, y in xy]
    arr = np.array(rows, np.float64).reshape(-1, 4)
    n = len(arr)
    return Detections(labels=labels, frame=arr[:, 0].astype(np.int64), view=arr[:, 1].astype(np.int64),
                      label=np.full(n, -1, np.int64), xy=arr[:, 2:4], confidence=np.ones(n))


def match_detections(detected: np.ndarray, truth: np.ndarray, visible: np.ndarray,
                     radius_px: float = 5.0) -> dict:
    """Score detections (N, 2) against true marker projections (L, 2) of which ``visible``
    (L,) are in view: optimal one-to-one matching within ``radius_px``.

    Returns counts (visible, matched, false_positives) and the rates: detection_rate =
    matched / visible, false_positive_rate = false_positives / visible, pixel_error_px =
    mean distance of the matches (NaN without matches)."""
    vis = np.flatnonzero(visible)
    det = np.asarray(detected, np.float64).reshape(-1, 2)
    matched_err = np.zeros(0)
    if len(vis) and len(det):
        d = np.linalg.norm(truth[vis][:, None] - det[None], axis=-1)       # (V, N)
        cost = np.where(d <= radius_px, d, 1e6)
        r, c = linear_sum_assignment(cost)
        ok = d[r, c] <= radius_px
        matched_err = d[r, c][ok]
    m = len(matched_err)
    V = max(len(vis), 1)
    return {"visible": int(len(vis)), "matched": m, "false_positives": int(len(det) - m),
            "detection_rate": m / V, "false_positive_rate": (len(det) - m) / V,
            "pixel_error_px": float(matched_err.mean()) if m else float("nan")}
