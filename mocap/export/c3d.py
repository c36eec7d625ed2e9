"""C3D export, written by ``ezc3d`` (the reference C3D library of the biomechanics community):
the landmarks as 3D points in millimetres, Z up (mocap's world axes), at the run's frame rate."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mocap.export.motion import Motion


def write_c3d(motion: Motion, path: str | Path, which: str = "landmarks") -> Path:
    import ezc3d

    if which == "tracker":
        if "tracker_landmarks" not in motion.per_frame:
            raise ValueError("this run's tracker reported no landmarks of its own (marker runs do)")
        names = tuple(str(n) for n in motion.per_frame["tracker_landmark_names"])
        pts = motion.per_frame["tracker_landmarks"]
    elif which in ("landmarks", "joints"):
        names, pts = ((motion.landmark_names, motion.landmarks) if which == "landmarks"
                      else (motion.joint_names, motion.joints))
    else:
        raise ValueError(f"which must be 'landmarks', 'joints' or 'tracker', got {which!r}")
    F, L = len(pts), len(names)
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(motion.fps)]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(names)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    data = np.ones((4, L, F))
    data[:3] = 1e3 * np.transpose(np.asarray(pts, np.float64), (2, 1, 0))
    c["data"]["points"] = data
    path = Path(path)
    c.write(str(path))
    return path
