"""The model-free baseline: robust per-frame triangulation of 2D keypoint detections.

Every keypoint of every frame on its own (no body, no time): RANSAC over the views — every
pair of its candidates in two views is a hypothesis, the one whose point projects within
``gate_px`` of a candidate in the most views (then the smallest error) wins — and a DLT on
that hypothesis's inliers (:func:`mocap.trackers.markers.startup.triangulate_candidates`, the
marker tracker's own start-up triangulation, :func:`mocap.cameras.triangulate`). A view
whose candidate is far from where the other views put the point (a left/right swap, another
person's limb) is an outlier and left out. Scored with the same joints and the same MPJPE as
a tracker (:class:`mocap.eval.by_name.NameScorer`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocap.cameras import Rig
from mocap.data.sequence import Detections
from mocap.energy.markers import arrange_detections
from mocap.trackers.markers.startup import pinhole_rig, triangulate_candidates


def robust_triangulation(rig: Rig, detections: Detections, names: Sequence[str], frames: int,
                         gate_px: float, min_views: int = 2,
                         hold: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Keypoints ``names`` (L) triangulated in frames 0..frames-1 -> (points (F, L, 3) world
    metres, inliers (F, L) views that agree). Where fewer than ``min_views`` views agree the
    point is NaN, or with ``hold`` the last triangulated value (NaN until there is one);
    ``inliers`` is 0 there either way."""
    pin = pinhole_rig(rig)
    points = np.full((frames, len(names), 3), np.nan)
    inliers = np.zeros((frames, len(names)), np.int64)
    for f in range(frames):
        obs = arrange_detections(detections.select(f), list(names), rig)
        points[f], inliers[f] = triangulate_candidates(pin, obs, gate_px, min_views)
        if hold and f:
            miss = ~np.isfinite(points[f, :, 0])
            points[f, miss] = points[f - 1, miss]
    return points, inliers


def score_triangulation(scorer, names: Sequence[str], points: np.ndarray) -> dict:
    """The metrics of :meth:`mocap.eval.by_name.NameScorer.score` for triangulated keypoints
    (F, L, 3) named ``names`` (our catalogue's names, as the detections' labels); frames or
    keypoints never triangulated (NaN) are left out of the means."""
    return scorer.score({n: points[:, i] for i, n in enumerate(names)})
