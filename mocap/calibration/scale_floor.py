"""Metres and a floor for a reconstruction known up to a similarity (extrinsics from people).

* floor: per frame the lowest foot keypoint (along the cameras' mean "up", minus their image y
  axes) is where a foot touches the ground. When those points cover an area (the person
  walked: their spread across is at least ``MIN_FLOOR_SPREAD`` of the body's length) a plane
  fit to them (least squares, the farthest quarter dropped twice) is the floor; when the person
  stayed on one spot the plane is not determined, and the floor's normal is the body's own
  up (the median direction from the feet to the shoulders and head), through the lowest foot
  points. Its normal pointing up becomes +z, the origin is the person's mean position on it.
* scale: a known length: a person's height (the median over frames of the top keypoint's
  height above the floor) or the distance between two keypoints (median over frames).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocap.calibration.errors import CalibrationInputError

#: keypoints on the feet, lowest first in spirit; those of the layout are used
FOOT_KEYPOINTS = ("l_heel", "r_heel", "l_toe", "r_toe", "l_small_toe", "r_small_toe", "l_ankle", "r_ankle")
#: the keypoint whose height above the floor is a person's height, best first
TOP_KEYPOINTS = ("head_top", "head", "nose")
#: keypoints averaged as the top of the trunk for the body's up direction
UPPER_KEYPOINTS = ("l_shoulder", "r_shoulder", "neck", "head", "head_top", "nose")
#: the foot contacts' spread across (std, m / body length) below which their plane is not trusted
MIN_FLOOR_SPREAD = 0.1


def _indices(labels: Sequence[str | None], wanted: Sequence[str]) -> list[int]:
    return [labels.index(w) for w in wanted if w in labels]


def body_up(points: np.ndarray, labels: Sequence[str | None]) -> tuple[np.ndarray, float]:
    """(unit median direction from the mid-feet to the upper body (3,), its median length)."""
    feet = _indices(labels, FOOT_KEYPOINTS)
    upper = _indices(labels, UPPER_KEYPOINTS)
    if not upper:
        raise CalibrationInputError("", f"the keypoint layout has none of {UPPER_KEYPOINTS}")
    v = np.nanmean(points[:, upper], axis=1) - np.nanmean(points[:, feet], axis=1)
    v = v[np.isfinite(v).all(1)]
    if len(v) == 0:
        raise CalibrationInputError("", "feet and upper body never reconstructed in one frame: no floor")
    n = np.linalg.norm(v, axis=1)
    u = np.median(v / n[:, None], axis=0)
    return u / np.linalg.norm(u), float(np.median(n))


def floor_frame(points: np.ndarray, labels: Sequence[str | None], camera_R: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, str]:
    """points (F, K, 3) (NaN: missing); camera_R (C, 3, 3) world-to-camera -> (R (3, 3),
    t (3,), how) with ``x_new = R x + t`` putting the floor at z = 0, z up; how: "plane of the
    feet" or "body's up axis"."""
    feet = _indices(labels, FOOT_KEYPOINTS)
    if not feet:
        raise CalibrationInputError("", "the keypoint layout names no foot keypoint: the floor cannot be "
                                        "found (give the floor another way or use a layout with feet)")
    up = -camera_R[:, 1, :].mean(0)
    up /= np.linalg.norm(up)
    P = points[:, feet]                                                   # (F, k, 3)
    h = np.where(np.isfinite(P).all(-1), P @ up, np.inf)
    low = P[np.arange(len(P)), np.argmin(h, axis=1)]
    low = low[np.isfinite(low).all(1) & np.isfinite(h.min(1))]
    if len(low) < 3:
        raise CalibrationInputError("", f"feet seen in {len(low)} frame(s), at least 3 needed for the floor")
    keep = np.ones(len(low), bool)
    u_body, length = body_up(points, labels)
    spread = np.linalg.svd(low - low.mean(0), compute_uv=False)[1] / np.sqrt(len(low))
    if spread >= MIN_FLOOR_SPREAD * length:
        how = "plane of the feet"
        for _ in range(3):
            c = low[keep].mean(0)
            n = np.linalg.svd(low[keep] - c)[2][2]
            n = n if n @ up > 0 else -n
            d = np.abs((low - c) @ n)
            keep = d <= np.quantile(d, 0.75) if len(low) >= 8 else keep
    else:
        how = "body's up axis"
        n = u_body if u_body @ up > 0 else -u_body
        h = low @ n
        c = low[np.argsort(h)[len(h) // 4]]                                  # a low foot contact
    z = n
    x = np.array([1.0, 0, 0]) - z[0] * z
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0, 1.0, 0]) - z[1] * z
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    centre = np.nanmean(points.reshape(-1, 3), axis=0)
    origin = centre - ((centre - c) @ n) * n
    return R, -R @ origin, how


def measured_height(points: np.ndarray, labels: Sequence[str | None]) -> float:
    """Median over frames of the top keypoint's z (points in the floor frame)."""
    top = _indices(labels, TOP_KEYPOINTS)
    if not top:
        raise CalibrationInputError("", f"the keypoint layout has none of {TOP_KEYPOINTS}: give --length")
    z = points[:, top[0], 2]
    z = z[np.isfinite(z)]
    if len(z) == 0:
        raise CalibrationInputError("", f"keypoint {labels[top[0]]!r} never reconstructed: give --length")
    return float(np.median(z))


def measured_length(points: np.ndarray, labels: Sequence[str | None], a: str, b: str) -> float:
    """Median over frames of the distance between keypoints a and b."""
    for name in (a, b):
        if name not in labels:
            raise ValueError(f"keypoint {name!r} not in the layout ({', '.join(x for x in labels if x)})")
    d = np.linalg.norm(points[:, labels.index(a)] - points[:, labels.index(b)], axis=-1)
    d = d[np.isfinite(d)]
    if len(d) == 0:
        raise CalibrationInputError("", f"keypoints {a!r} and {b!r} are never reconstructed together")
    return float(np.median(d))
