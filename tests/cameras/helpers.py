"""Test helpers: random but well-conditioned cameras with OpenCV distortion."""

from __future__ import annotations

import numpy as np

from mocap.cameras import Camera, Rig, look_at_rotation


def random_camera(rng: np.random.Generator, name: str, distortion: bool = True) -> Camera:
    """A camera 3-5 m from the origin looking roughly at it (with a random roll), random
    intrinsics and moderate distortion."""
    azimuth = rng.uniform(0, 2 * np.pi)
    dist_m = rng.uniform(3.0, 5.0)
    position = np.array([dist_m * np.cos(azimuth), dist_m * np.sin(azimuth),
                         rng.uniform(0.5, 2.5)])
    target = rng.normal(0.0, 0.2, 3) + np.array([0.0, 0.0, 1.0])
    R0 = look_at_rotation(position, target)
    roll = rng.uniform(-0.3, 0.3)
    Rz = np.array([[np.cos(roll), -np.sin(roll), 0], [np.sin(roll), np.cos(roll), 0],
                   [0, 0, 1]])
    R = Rz @ R0
    width, height = int(rng.integers(600, 1300)), int(rng.integers(450, 1000))
    f = rng.uniform(0.9, 1.5) * width
    K = np.array([[f, 0.0, width / 2 + rng.uniform(-20, 20)],
                  [0.0, f * rng.uniform(0.98, 1.02), height / 2 + rng.uniform(-20, 20)],
                  [0.0, 0.0, 1.0]])
    dist = None
    if distortion:
        dist = [rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.1), rng.uniform(-0.005, 0.005),
                rng.uniform(-0.005, 0.005), rng.uniform(-0.05, 0.05)]
    return Camera(name=name, K=K, dist=dist, R=R, t=-R @ position, width=width, height=height)


def random_rig(seed: int, num_cameras: int = 4, distortion: bool = True) -> Rig:
    rng = np.random.default_rng(seed)
    return Rig(tuple(random_camera(rng, f"cam_{i:02d}", distortion) for i in range(num_cameras)))


def points_near_origin(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3) world points in a 1 x 1 x 1.8 m box around a standing person."""
    return rng.uniform([-0.5, -0.5, 0.0], [0.5, 0.5, 1.8], size=(n, 3))
