"""C3D export, written by ``ezc3d`` (the reference C3D library of the biomechanics community):
the landmarks as 3D points in millimetres, Z up (mocap's world axes), at the run's frame rate."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mocap.export.motion import Motion


def write_c3d(motion: Motion, path: str | Path, which: str = "landmarks") -> Path:
    from mocap.export.trc import motion_points

    names, pts = motion_points(motion, which)
    return write_points_c3d(names, pts, motion.fps, path)


def write_points_c3d(names, pts: np.ndarray, fps: float, path: str | Path) -> Path:
    """Points (F, L, 3) world metres named ``names`` (L,) (several people: ``p<id>_<marker>``;
    NaN where a point is missing: written as NaN, which ezc3d reads back as NaN)."""
    import ezc3d

    F, L = len(pts), len(names)
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(fps)]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(names)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    data = np.ones((4, L, F))
    data[:3] = 1e3 * np.transpose(np.asarray(pts, np.float64), (2, 1, 0))
    c["data"]["points"] = data
    path = Path(path)
    c.write(str(path))
    return path
