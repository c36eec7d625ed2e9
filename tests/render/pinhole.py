"""A minimal pinhole camera for the render tests (K, R, t; no distortion)."""

from __future__ import annotations

import numpy as np


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera (R (3, 3), t (3,)) of an OpenCV camera (x right, y down, z forward)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    return R, -R @ eye


def ring_cameras(num: int = 4, radius: float = 3.5, height: float = 1.5, focal: float = 700.0,
                 size: int = 500) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """num cameras (K, R, t) on a circle around the z axis, looking at (0, 0, 1)."""
    c = (size - 1) / 2
    K = np.array([[focal, 0, c], [0, focal, c], [0, 0, 1]])
    cams = []
    for k in range(num):
        a = 2 * np.pi * k / num
        R, t = look_at([radius * np.cos(a), radius * np.sin(a), height], [0.0, 0.0, 1.0])
        cams.append((K, R, t))
    return cams


def project(points: np.ndarray, cams) -> tuple[np.ndarray, np.ndarray]:
    """points (..., V, 3) world -> pixels (..., C, V, 2) and depth (..., C, V)."""
    pts = np.asarray(points, float)
    pix, dep = [], []
    for K, R, t in cams:
        pc = pts @ R.T + t
        z = pc[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = pc[..., :2] / z[..., None]
        pix.append(uv * K[[0, 1], [0, 1]] + K[[0, 1], [2, 2]])
        dep.append(z)
    return np.stack(pix, axis=-3), np.stack(dep, axis=-2)
