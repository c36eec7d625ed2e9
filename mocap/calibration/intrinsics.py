"""Intrinsics of one camera from views of a board: ``cv2.calibrateCamera``, then the views whose
reprojection error stands out are dropped and the camera calibrated again.

With few views (fewer than :attr:`IntrinsicsSettings.full_model_views`) the lens model is
k1, k2 only (no tangential terms, no k3): a handful of board views cannot separate the
higher terms from the focal length and principal point.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from mocap.calibration.boards import Board
from mocap.calibration.errors import CalibrationInputError


@dataclass(frozen=True)
class IntrinsicsSettings:
    """min_views: board views a camera needs (after dropping outliers); outlier_factor: a view
    whose RMS reprojection error exceeds ``outlier_factor`` x the median of the views' (and
    ``min_outlier_px``) is dropped; full_model_views: from this many views on, k3 and the
    tangential terms are estimated too."""

    min_views: int = 4
    outlier_factor: float = 2.5
    min_outlier_px: float = 0.5
    full_model_views: int = 15


@dataclass(frozen=True)
class Intrinsics:
    """K (3, 3); dist (5,); size (width, height); rms: px over kept views; view_errors: RMS px
    per kept view (name -> px); dropped: name -> RMS px of the views dropped as outliers;
    poses: name -> (rvec (3,), tvec (3,)) board-to-camera of the kept views."""

    camera: str
    K: np.ndarray
    dist: np.ndarray
    size: tuple[int, int]
    rms: float
    view_errors: dict[str, float]
    dropped: dict[str, float] = field(default_factory=dict)
    poses: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


def _calibrate(obj: list[np.ndarray], img: list[np.ndarray], size: tuple[int, int], flags: int):
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        [o.astype(np.float32) for o in obj], [i.astype(np.float32).reshape(-1, 1, 2) for i in img],
        size, None, None, flags=flags,
        criteria=(cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 200, 1e-12))
    errors = []
    for o, i, r, t in zip(obj, img, rvecs, tvecs, strict=True):
        p, _ = cv2.projectPoints(o, r, t, K, dist)
        errors.append(float(np.sqrt(np.mean(np.sum((p.reshape(-1, 2) - i) ** 2, axis=1)))))
    d = np.zeros(5)
    d[:min(5, dist.size)] = dist.reshape(-1)[:5]
    return K, d, np.array(errors), [(np.asarray(r).reshape(3), np.asarray(t).reshape(3))
                                    for r, t in zip(rvecs, tvecs, strict=True)]


def calibrate_intrinsics(camera: str, views: dict[str, tuple[np.ndarray, np.ndarray]], board: Board,
                         size: tuple[int, int], settings: IntrinsicsSettings = IntrinsicsSettings()
                         ) -> Intrinsics:
    """views: view name -> (corners (N, 2) px, ids (N,)) of the board found there; size:
    (width, height). Raises :class:`CalibrationInputError` with fewer than ``min_views``
    views (before or after dropping outliers)."""
    names = sorted(views)
    if len(names) < settings.min_views:
        raise CalibrationInputError(camera, f"the board was found in {len(names)} view(s), at least "
                                            f"{settings.min_views} are needed: add images of the board "
                                            "at different angles and distances")
    obj_all = board.object_points()
    obj = [obj_all[views[n][1]] for n in names]
    img = [views[n][0] for n in names]
    flags = 0 if len(names) >= settings.full_model_views else (
        cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3)
    K, dist, err, poses = _calibrate(obj, img, size, flags)
    limit = max(settings.outlier_factor * float(np.median(err)), settings.min_outlier_px)
    keep = err <= limit
    dropped: dict[str, float] = {}
    if not keep.all() and keep.sum() >= settings.min_views:
        dropped = {n: float(e) for n, e, k in zip(names, err, keep, strict=True) if not k}
        names = [n for n, k in zip(names, keep, strict=True) if k]
        obj = [o for o, k in zip(obj, keep, strict=True) if k]
        img = [i for i, k in zip(img, keep, strict=True) if k]
        K, dist, err, poses = _calibrate(obj, img, size, flags)
    rms = float(np.sqrt(np.mean(err ** 2)))
    return Intrinsics(camera, K, dist, tuple(size), rms, dict(zip(names, map(float, err), strict=True)),
                      dropped, dict(zip(names, poses, strict=True)))
