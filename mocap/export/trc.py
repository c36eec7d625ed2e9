"""TRC export: marker trajectories as OpenSim and Pose2Sim read them (tab-separated text,
millimetres, Y up with Pose2Sim's axis permutation, ``axes.OPENSIM_FROM_WORLD``).

    PathFileType  4  (X/Y/Z)  <file name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    <fps>  <fps>  F  L  mm  <fps>  1  F
    Frame#  Time  <marker 1>  <tab>  <tab>  <marker 2> ...
    <tab>  <tab>  X1  Y1  Z1  X2  Y2  Z2 ...
    <blank line>
    1  0.000000  x  y  z ...        (frames numbered from 1)

The markers are the run's landmarks (``landmarks``: the body's default landmark set), its
joints (``which="joints"``) or the landmarks a marker tracker fitted, named after the
detection labels (``which="tracker"``; blank where not reported, e.g. frame 0).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mocap.export.axes import OPENSIM_FROM_WORLD, points_to
from mocap.export.motion import Motion


def motion_points(motion: Motion, which: str = "landmarks") -> tuple[tuple[str, ...], np.ndarray]:
    """(names, points (F, L, 3) world metres) of a motion's ``which`` markers: landmarks,
    joints or tracker (a marker tracker's own landmarks)."""
    if which == "landmarks":
        names, pts = motion.landmark_names, motion.landmarks
    elif which == "joints":
        names, pts = motion.joint_names, motion.joints
    elif which == "tracker":
        if "tracker_landmarks" not in motion.per_frame:
            raise ValueError("this run's tracker reported no landmarks of its own (marker runs do)")
        names = tuple(str(n) for n in motion.per_frame["tracker_landmark_names"])
        pts = motion.per_frame["tracker_landmarks"]
    else:
        raise ValueError(f"which must be 'landmarks', 'joints' or 'tracker', got {which!r}")
    return names, pts


def trc_text(motion: Motion, which: str = "landmarks", file_name: str = "motion.trc") -> str:
    names, pts = motion_points(motion, which)
    return points_trc_text(names, pts, motion.fps, motion.timestamps, file_name)


def points_trc_text(names, pts: np.ndarray, fps: float, timestamps: np.ndarray,
                    file_name: str = "motion.trc") -> str:
    """The TRC text of points (F, L, 3) world metres named ``names`` (L,) (NaN: blank)."""
    F, L = len(pts), len(names)
    mm = 1e3 * points_to(OPENSIM_FROM_WORLD, np.asarray(pts, np.float64))
    fps = f"{fps:.2f}"
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{file_name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
             f"{fps}\t{fps}\t{F}\t{L}\tmm\t{fps}\t1\t{F}",
             "Frame#\tTime\t" + "\t\t\t".join(names) + "\t\t",
             "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, L + 1)),
             ""]
    for f in range(F):
        vals = "\t".join("" if not np.isfinite(v) else f"{v:.4f}" for v in mm[f].ravel())
        lines.append(f"{f + 1}\t{timestamps[f]:.6f}\t{vals}")
    return "\n".join(lines) + "\n"


def write_trc(motion: Motion, path: str | Path, which: str = "landmarks",
              file_name: str | None = None) -> Path:
    """file_name: the name the header gives (default: the file's own)."""
    path = Path(path)
    path.write_text(trc_text(motion, which, file_name or path.name))
    return path


def write_points_trc(names, pts: np.ndarray, fps: float, timestamps: np.ndarray, path: str | Path,
                     file_name: str | None = None) -> Path:
    """:func:`points_trc_text` to ``path`` (several people: names ``p<id>_<marker>``)."""
    path = Path(path)
    path.write_text(points_trc_text(names, pts, fps, timestamps, file_name or path.name))
    return path
