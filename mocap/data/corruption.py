"""Observation models: how the synthetic generator degrades perfect observations.

``DetectionModel``  Canton-Ferrer et al. 2010, Sec. 4.1: each visible marker is detected with
                    probability ``detection_rate`` (a miss otherwise), at its projection plus
                    Gaussian noise of ``noise_px``; each view and frame also gets false
                    positives, Poisson with mean ``false_positive_rate`` x markers, placed
                    uniformly in the subject's bounding box (grown by 30 %) with a random label.
``SilhouetteNoise`` background-subtraction errors: erosion/dilation of the outline, spurious
                    blobs, holes, missing body parts, and a cast shadow at the feet.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class DetectionModel:
    detection_rate: float = 1.0
    false_positive_rate: float = 0.0
    noise_px: float = 0.0
    labelled: bool = True

    def __post_init__(self) -> None:
        if not 0.0 <= self.detection_rate <= 1.0:
            raise ValueError(f"detection_rate must be in [0, 1], got {self.detection_rate}")
        if self.false_positive_rate < 0 or self.noise_px < 0:
            raise ValueError("false_positive_rate and noise_px must be >= 0")

    def sample(self, pixels: np.ndarray, visible: np.ndarray, width: int, height: int,
               rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Detections of one frame and view.

        pixels: (L, 2) true projections; visible: (L,) bool -> (label (N,), xy (N, 2),
        confidence (N,)), all inside the image.
        """
        L = len(pixels)
        hit = visible & (rng.random(L) < self.detection_rate)
        label = np.flatnonzero(hit)
        xy = pixels[hit] + rng.normal(0.0, self.noise_px, size=(len(label), 2))
        n_fp = rng.poisson(self.false_positive_rate * L) if self.false_positive_rate > 0 else 0
        if n_fp:
            seen = pixels[visible] if visible.any() else pixels
            lo, hi = seen.min(axis=0), seen.max(axis=0)
            pad = 0.3 * (hi - lo) + 10
            fp = rng.uniform(lo - pad, hi + pad, size=(n_fp, 2))
            label = np.concatenate([label, rng.integers(0, L, size=n_fp)])
            xy = np.concatenate([xy, fp])
        conf = np.clip(rng.normal(0.85, 0.1, size=len(label)), 0.05, 1.0)
        inside = (xy[:, 0] >= 0) & (xy[:, 0] <= width - 1) & (xy[:, 1] >= 0) & (xy[:, 1] <= height - 1)
        if not self.labelled:
            label = np.full_like(label, -1)
        return label[inside], xy[inside], conf[inside]


@dataclass(frozen=True)
class SilhouetteNoise:
    dilate_px: int = 0          # grow the outline by up to this many pixels (random per view)
    erode_px: int = 0           # shrink it by up to this many pixels
    blobs: float = 0.0          # mean number of spurious foreground blobs per view
    holes: float = 0.0          # mean number of holes inside the silhouette per view
    missing_part: float = 0.0   # probability that a view loses a rectangle of the body
    blob_radius_px: float = 12.0
    shadow: float = 0.0         # probability that a view gets a cast shadow: a filled ellipse
                                # attached at the lowest part of the silhouette (the feet)
    shadow_size: float = 0.6    # the shadow's width, as a fraction of the silhouette's width

    @property
    def active(self) -> bool:
        return bool(self.dilate_px or self.erode_px or self.blobs or self.holes or self.missing_part
                    or self.shadow)

    def apply(self, mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A noisy copy of one (H, W) bool silhouette."""
        m = mask.astype(np.uint8)
        h, w = m.shape
        if self.dilate_px:
            r = int(rng.integers(0, self.dilate_px + 1))
            if r:
                m = cv2.dilate(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
        if self.erode_px:
            r = int(rng.integers(0, self.erode_px + 1))
            if r:
                m = cv2.erode(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
        ys, xs = np.nonzero(mask)
        if len(ys):
            y0, y1, x0, x1 = ys.min(), ys.max(), xs.min(), xs.max()
            rad = max(2, int(self.blob_radius_px))
            for _ in range(rng.poisson(self.blobs) if self.blobs else 0):
                c = (int(rng.uniform(0, w)), int(rng.uniform(0, h)))
                cv2.circle(m, c, int(rng.uniform(0.5, 1.5) * rad), 1, -1)
            for _ in range(rng.poisson(self.holes) if self.holes else 0):
                i = int(rng.integers(len(ys)))
                cv2.circle(m, (int(xs[i]), int(ys[i])), int(rng.uniform(0.3, 1.0) * rad), 0, -1)
            if self.missing_part and rng.random() < self.missing_part:
                bw, bh = int((x1 - x0) * rng.uniform(0.2, 0.4)), int((y1 - y0) * rng.uniform(0.1, 0.25))
                cx, cy = int(rng.uniform(x0, x1)), int(rng.uniform(y0, y1))
                m[max(0, cy - bh // 2):cy + bh // 2, max(0, cx - bw // 2):cx + bw // 2] = 0
            if self.shadow and rng.random() < self.shadow:
                # centred on the lowest silhouette pixels, flattened like a shadow on the floor
                low = ys >= y1 - max(2, int(0.03 * (y1 - y0)))
                cx = int(xs[low].mean() + rng.normal(0, 0.05) * (x1 - x0))
                ax = max(3, int(self.shadow_size * (x1 - x0 + 1) * rng.uniform(0.6, 1.2) / 2))
                ay = max(2, int(ax * rng.uniform(0.2, 0.4)))
                ang = float(rng.uniform(-20, 20))
                cv2.ellipse(m, (cx, int(y1)), (ax, ay), ang, 0, 360, 1, -1)
        return m.astype(bool)
