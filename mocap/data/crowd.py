"""Synthetic scenes with several people, as a keypoint detector sees them: per frame and view,
one skeleton of labelled keypoints per visible person, grouped by ``Detections.person`` (the
detector's per-view index, shuffled so that it says nothing about identity across views or
frames). For tests and figures of the multi-person start-up and tracking.

    det, points = crowd_detections(body, rig, chis, alphas, labels, noise_px=1.0, seed=0)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig, project
from mocap.data.sequence import Detections
from mocap.trackers.marker_landmarks import make_landmark_set


def crowd_detections(body: BodyModel, rig: Rig, chis: np.ndarray, alphas: np.ndarray,
                     labels: Sequence[str], noise_px: float = 1.0, seed: int = 0,
                     confidence: float = 0.8) -> tuple[Detections, np.ndarray]:
    """chis: (N, F, D) poses of N people over F frames; alphas: (N, K) their shapes; labels:
    keypoint names of the landmark catalogue. Returns the detections (every keypoint in
    front of a camera and inside its image; pixel noise ``noise_px``) and the true
    keypoints (N, F, L, 3) world metres."""
    rng = np.random.default_rng(seed)
    lms = make_landmark_set(body, list(labels))
    chis = np.asarray(chis, np.float64)
    N, F, _ = chis.shape
    pts = np.stack([lms.positions(body.shaped(alphas[n]), chis[n]).astype(np.float64) for n in range(N)])
    rows = []
    sizes = np.asarray(rig.sizes, np.float64)                          # (C, 2) width, height
    for f in range(F):
        for c in range(len(rig)):
            order = rng.permutation(N)                                 # the detector's own order
            for slot, n in enumerate(order):
                px, depth = project(rig[c], pts[n, f], return_depth=True)
                px = px + rng.normal(0.0, noise_px, px.shape)
                ok = (depth > 0.1) & np.all((px >= 0) & (px < sizes[c]), axis=1)
                for k in np.flatnonzero(ok):
                    rows.append((f, c, k, px[k, 0], px[k, 1], confidence, slot))
    a = np.array(rows, np.float64).reshape(-1, 7)
    det = Detections(tuple(lms.names), a[:, 0].astype(np.int64), a[:, 1].astype(np.int64),
                     a[:, 2].astype(np.int64), a[:, 3:5], a[:, 5], a[:, 6].astype(np.int64))
    return det, pts
