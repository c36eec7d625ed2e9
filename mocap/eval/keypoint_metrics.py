"""Accuracy without ground truth, for real recordings with 2D keypoints: how well the
estimated landmarks reproject onto the detections of every view, how stable the lengths of
the bones between landmarks are, and how much the landmarks jitter from frame to frame.

Each metric is also computed for a model-free baseline: the detections triangulated frame by
frame (DLT over the views that see a keypoint), so a tracker's numbers can be read against
what plain triangulation gives on the same data.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocap.body.catalogue import make_landmark_set
from mocap.body.model import BodyModel
from mocap.cameras import Rig, project, triangulate
from mocap.data.sequence import Detections
from mocap.data.sequence import Sequence as MocapSequence
from mocap.eval.estimates import FrameEstimate

#: landmark pairs joined by one bone (used when both are present)
BONES: tuple[tuple[str, str], ...] = (
    ("l_shoulder", "l_elbow"), ("l_elbow", "l_wrist"), ("r_shoulder", "r_elbow"), ("r_elbow", "r_wrist"),
    ("l_hip", "l_knee"), ("l_knee", "l_ankle"), ("r_hip", "r_knee"), ("r_knee", "r_ankle"),
    ("l_shoulder", "r_shoulder"), ("l_hip", "r_hip"),
)


def detection_residuals(rig: Rig, landmarks: np.ndarray, names: Sequence[str],
                        detections: Detections) -> tuple[np.ndarray, np.ndarray]:
    """Reprojection residuals of landmarks (F, L, 3) world metres against labelled detections
    (distorted pixels). Detections of labels not in ``names`` or of frames >= F are skipped;
    where a (frame, view, label) has several detections the nearest counts.
    Returns (errors (N,) pixels, views (N,))."""
    F = len(landmarks)
    index = {n: i for i, n in enumerate(names)}
    to_lm = np.array([index.get(n, -1) for n in detections.labels] + [-1])
    lm = to_lm[np.where(detections.label >= 0, detections.label, len(detections.labels))]
    keep = (lm >= 0) & (detections.frame < F) & (detections.frame >= 0)
    f, c, lm, xy = detections.frame[keep], detections.view[keep], lm[keep], detections.xy[keep]
    px = project(rig, landmarks)                                          # (F, C, L, 2)
    err = np.linalg.norm(px[f, c, lm] - xy, axis=1)
    key = (f * len(rig) + c) * len(names) + lm
    order = np.lexsort((err, key))                                         # nearest first per key
    first = np.ones(len(order), bool)
    first[1:] = key[order][1:] != key[order][:-1]
    sel = order[first]
    ok = np.isfinite(err[sel])
    return err[sel][ok], c[sel][ok]


def triangulate_detections(rig: Rig, detections: Detections, names: Sequence[str], frames: int,
                           min_confidence: float = 0.0) -> np.ndarray:
    """Per-frame DLT of labelled detections (one per frame, view and label: the most
    confident) -> (F, L, 3), NaN where fewer than 2 views see a landmark."""
    C, L = len(rig), len(names)
    index = {n: i for i, n in enumerate(names)}
    to_lm = np.array([index.get(n, -1) for n in detections.labels] + [-1])
    lm = to_lm[np.where(detections.label >= 0, detections.label, len(detections.labels))]
    keep = (lm >= 0) & (detections.frame < frames) & (detections.confidence >= min_confidence)
    px = np.full((C, frames * L, 2), np.nan)
    conf = np.full((C, frames * L), -np.inf)
    for i in np.flatnonzero(keep):                  # vectorising this buys little (N ~ 1e4)
        col = detections.frame[i] * L + lm[i]
        c = detections.view[i]
        if detections.confidence[i] > conf[c, col]:
            conf[c, col], px[c, col] = detections.confidence[i], detections.xy[i]
    return triangulate(rig, px).reshape(frames, L, 3)


def bone_lengths(landmarks: np.ndarray, names: Sequence[str],
                 bones: Sequence[tuple[str, str]] = BONES) -> dict[str, np.ndarray]:
    """{"a-b": (F,) lengths in metres} for the bones whose two landmarks are in ``names``."""
    idx = {n: i for i, n in enumerate(names)}
    return {f"{a}-{b}": np.linalg.norm(landmarks[:, idx[a]] - landmarks[:, idx[b]], axis=-1)
            for a, b in bones if a in idx and b in idx}


def jitter_mm(landmarks: np.ndarray) -> float:
    """Mean norm of the second difference x_{t+1} - 2 x_t + x_{t-1} over frames and
    landmarks (mm per frame^2); NaN entries are skipped."""
    if len(landmarks) < 3:
        return float("nan")
    acc = np.linalg.norm(landmarks[2:] - 2 * landmarks[1:-1] + landmarks[:-2], axis=-1)
    return float(1e3 * np.nanmean(acc)) if np.isfinite(acc).any() else float("nan")


def keypoint_metrics(rig: Rig, landmarks: np.ndarray, names: Sequence[str], detections: Detections) -> dict:
    """Metrics of estimated landmarks (F, L, 3) against a recording's detections.

    Keys: reprojection_median_px, reprojection_median_px_per_view {view: px},
    bone_length_std_mm (mean over bones of the std over frames), bone_length_mm {bone: mean},
    jitter_mm.
    """
    err, view = detection_residuals(rig, landmarks, names, detections)
    bones = bone_lengths(landmarks, names)
    return {
        "reprojection_median_px": float(np.median(err)) if len(err) else float("nan"),
        "reprojection_median_px_per_view": {
            rig.names[c]: float(np.median(err[view == c])) if np.any(view == c) else float("nan")
            for c in range(len(rig))},
        "bone_length_std_mm": (float(1e3 * np.mean([np.nanstd(v) for v in bones.values()])) if bones
                               else float("nan")),
        "bone_length_mm": {k: float(1e3 * np.nanmean(v)) for k, v in bones.items()},
        "jitter_mm": jitter_mm(landmarks),
    }


def keypoint_run_metrics(body: BodyModel, seq: MocapSequence, estimates: list[FrameEstimate]) -> dict:
    """:func:`keypoint_metrics` of a run's estimates (one per frame, frame 0 the
    initialisation) on the landmarks named by the detection labels, plus the same metrics of
    per-frame triangulation under ``triangulation``."""
    det = seq.detections
    lms = make_landmark_set(body, "auto", det.labels)
    chis = np.stack([e.chi for e in estimates])
    X = lms.positions(body.shaped(estimates[-1].alpha), chis).astype(np.float64)
    out = keypoint_metrics(seq.rig, X, lms.names, det)
    T = triangulate_detections(seq.rig, det, lms.names, len(estimates))
    out["triangulation"] = keypoint_metrics(seq.rig, T, lms.names, det)
    return out
