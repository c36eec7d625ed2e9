"""Extrinsics from points of known 3D coordinates whose pixel positions are given in a file.

File formats (world coordinates in metres, pixels as OpenCV: the centre of the top-left pixel
is (0, 0)):

* JSON::

      {"points": {"A": [x, y, z], "B": [x, y, z], ...},
       "cameras": {"cam01": {"A": [u, v], "B": [u, v], ...}, "cam02": {...}}}

* CSV with the header ``camera,point,x,y,z,u,v``, one row per point seen in a camera.

Each camera needs at least 4 points (6 when they are not on one plane is safer):
``cv2.solvePnP`` (SQPnP) then ``cv2.solvePnPRefineLM``. The world frame is the points'.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from mocap.calibration.errors import CalibrationInputError

#: points a camera needs
MIN_POINTS = 4


def read_known_points(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray, list[str]]]:
    """camera -> (world points (N, 3), pixels (N, 2), point names)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"known points file not found: {path}")
    out: dict[str, tuple[list, list, list]] = {}
    if path.suffix.lower() == ".csv":
        with path.open(newline="") as fh:
            rows = list(csv.DictReader(fh))
        need = {"camera", "point", "x", "y", "z", "u", "v"}
        if not rows or not need <= set(rows[0]):
            raise ValueError(f"{path}: expected a CSV with the header camera,point,x,y,z,u,v")
        for i, r in enumerate(rows, start=2):
            try:
                X, uv = [float(r[k]) for k in "xyz"], [float(r[k]) for k in "uv"]
            except (TypeError, ValueError):
                raise ValueError(f"{path}: line {i}: x, y, z, u, v must be numbers") from None
            o = out.setdefault(r["camera"], ([], [], []))
            o[0].append(X)
            o[1].append(uv)
            o[2].append(r["point"])
    else:
        try:
            data = json.loads(path.read_text())
            points, cams = data["points"], data["cameras"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{path}: expected JSON with 'points' and 'cameras' ({exc})") from None
        for cam, seen in cams.items():
            o = out.setdefault(cam, ([], [], []))
            for name, uv in seen.items():
                if name not in points:
                    raise ValueError(f"{path}: camera {cam!r}: point {name!r} has no entry in 'points'")
                o[0].append(points[name])
                o[1].append(uv)
                o[2].append(name)
    result = {}
    for cam, (X, uv, names) in out.items():
        X, uv = np.asarray(X, float), np.asarray(uv, float)
        if X.shape != (len(names), 3) or uv.shape != (len(names), 2) or not np.isfinite(X).all() \
                or not np.isfinite(uv).all():
            raise ValueError(f"{path}: camera {cam!r}: points need 3 finite coordinates and pixels 2")
        result[cam] = (X, uv, names)
    return result


def calibrate_known_points(names: Sequence[str], K: np.ndarray, dist: np.ndarray,
                           known: dict[str, tuple[np.ndarray, np.ndarray, list[str]]]
                           ) -> tuple[np.ndarray, list[np.ndarray]]:
    """(cams (C, 6) rvec | t, residuals per camera (N, 2) px). Cameras are matched to the
    file's by name ignoring case and separators."""
    def key(s: str) -> str:
        return "".join(ch for ch in s.lower() if ch.isalnum())
    by_key = {key(k): v for k, v in known.items()}
    for n in names:
        got = by_key.get(key(n))
        if got is None:
            raise CalibrationInputError(n, f"has no points in the known-points file (cameras there: "
                                           f"{sorted(known)}): add its pixel positions")
        if len(got[0]) < MIN_POINTS:
            raise CalibrationInputError(n, f"has {len(got[0])} known points, at least {MIN_POINTS} are "
                                           "needed: click more points of known coordinates")
    cams, residuals = [], []
    for c, n in enumerate(names):
        X, uv, _ = by_key[key(n)]
        ok, r, t = cv2.solvePnP(X, uv, K[c], dist[c], flags=cv2.SOLVEPNP_SQPNP)
        if not ok:
            raise CalibrationInputError(n, "solvePnP failed on its known points: check the pixel positions")
        r, t = cv2.solvePnPRefineLM(X, uv, K[c], dist[c], r, t)
        p, _ = cv2.projectPoints(X, r, t, K[c], dist[c])
        cams.append(np.concatenate([r.reshape(3), t.reshape(3)]))
        residuals.append(p.reshape(-1, 2) - uv)
    return np.stack(cams), residuals
