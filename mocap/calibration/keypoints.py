"""A person's 2D keypoints per view from OpenPose JSON folders (one folder per camera, the
Pose2Sim layout read by :mod:`mocap.data.openpose`), matched across views by frame number.

Every file may hold several people; the person calibrated on is, per view and frame, the
largest (the diagonal of the box around their confident keypoints): the person walking
through the capture volume, nearer the cameras than bystanders.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from mocap.calibration.errors import CalibrationInputError
from mocap.data.openpose import LAYOUTS, read_keypoint_folders


@dataclass(frozen=True)
class ViewKeypoints:
    """frames (F,) frame numbers; xy (C, F, K, 2) px; confidence (C, F, K) (0: not seen);
    labels (K,): landmark names of the layout (None: unnamed)."""

    names: tuple[str, ...]
    frames: np.ndarray
    xy: np.ndarray
    confidence: np.ndarray
    labels: tuple[str | None, ...]

    def flat(self) -> tuple[np.ndarray, np.ndarray]:
        """(xy (C, F*K, 2), confidence (C, F*K))."""
        C, F, K = self.confidence.shape
        return self.xy.reshape(C, F * K, 2), self.confidence.reshape(C, F * K)


def largest_person(people: np.ndarray, min_confidence: float) -> int | None:
    """Index of the largest person of (N, K, 3), None when nobody has 2 confident keypoints."""
    best, size = None, 0.0
    for i, p in enumerate(people):
        ok = p[:, 2] >= min_confidence
        if ok.sum() >= 2:
            d = float(np.linalg.norm(p[ok, :2].max(0) - p[ok, :2].min(0)))
            if d > size:
                best, size = i, d
    return best


def read_view_keypoints(folder: str | Path, names: Sequence[str], layout: str = "BODY_25B",
                        min_confidence: float = 0.3, frames: int | None = None) -> ViewKeypoints:
    """Keypoints of the largest person per view and frame; ``names``: the cameras, matched to
    the folders by name (``cam_01`` <-> ``cam01_json``); frames: the first N only."""
    folder = Path(folder)
    if layout not in LAYOUTS:
        raise ValueError(f"keypoint layout {layout!r} unknown; one of {', '.join(LAYOUTS)}")
    per_view = read_keypoint_folders(SimpleNamespace(names=tuple(names)), folder, len(LAYOUTS[layout]))
    numbers = np.array(sorted(per_view[0]))[:frames]
    C, F, K = len(names), len(numbers), len(LAYOUTS[layout])
    xy = np.zeros((C, F, K, 2))
    conf = np.zeros((C, F, K))
    for c, view in enumerate(per_view):
        for f, n in enumerate(numbers):
            i = largest_person(view[n], min_confidence)
            if i is not None:
                xy[c, f] = view[n][i, :, :2]
                conf[c, f] = view[n][i, :, 2]
    for c, n in enumerate(names):
        if not (conf[c] >= min_confidence).any():
            raise CalibrationInputError(n, f"no keypoint with confidence >= {min_confidence} in {folder}: "
                                           "check the camera's keypoint folder")
    return ViewKeypoints(tuple(names), numbers, xy, conf, LAYOUTS[layout])
