"""Textured RGB (and depth) rendering of the body with pyrender, headless through EGL.

Used by the synthetic data generator for images (SIFT features for the local optimizer,
coloured markers for the marker detector). Distortion is applied after rendering by
remapping the ideal pinhole image, so rendered images follow the full OpenCV model.

Needs ``PYOPENGL_PLATFORM=egl`` (set here if unset) and the EGL/Mesa system libraries
(scripts/setup_env.sh installs them).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from mocap.cameras import Camera
from mocap.cameras.projection import undistort_points

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
if not hasattr(np, "infty"):      # pyrender 0.1.45 still uses the alias numpy 2 removed
    np.infty = np.inf  # noqa: NPY201

# OpenCV camera axes (x right, y down, z forward) -> OpenGL (x right, y up, z backward)
_CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass(frozen=True)
class RenderMesh:
    """A mesh to draw: vertices (V, 3) world metres, faces (F, 3), colours (V, 3|4) uint8."""

    vertices: np.ndarray
    faces: np.ndarray
    colors: np.ndarray


class RGBRenderer:
    """An offscreen renderer of one image size; reuse it across frames and views."""

    def __init__(self, width: int, height: int, background=(40, 40, 48)):
        try:
            import pyrender
        except Exception as exc:  # ImportError, or OpenGL/EGL library errors
            raise RuntimeError(
                "RGB rendering needs pyrender with EGL (Debian: libegl1 libegl-mesa0 "
                f"libgl1-mesa-dri libgl1 libopengl0; PYOPENGL_PLATFORM=egl): {exc}") from exc
        self._pyrender = pyrender
        self.width, self.height = int(width), int(height)
        self.background = np.asarray(background, np.float32) / 255.0
        self._renderer = pyrender.OffscreenRenderer(self.width, self.height)

    def close(self) -> None:
        self._renderer.delete()

    def __enter__(self) -> RGBRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def render(self, camera: Camera, meshes: Sequence[RenderMesh]) -> tuple[np.ndarray, np.ndarray]:
        """Colour (H, W, 3) uint8 and depth (H, W) float32 metres (0 = background)."""
        pr = self._pyrender
        if (camera.width, camera.height) != (self.width, self.height):
            raise ValueError(f"camera {camera.name!r} is {camera.width}x{camera.height}, "
                             f"renderer is {self.width}x{self.height}")
        scene = pr.Scene(bg_color=np.r_[self.background, 1.0], ambient_light=[0.35] * 3)
        for m in meshes:
            import trimesh

            tm = trimesh.Trimesh(m.vertices, m.faces, vertex_colors=m.colors, process=False)
            scene.add(pr.Mesh.from_trimesh(tm, smooth=True))
        K = camera.K
        # GL samples pixel i at i + 0.5, OpenCV at i: shift the principal point by half a pixel
        cam = pr.IntrinsicsCamera(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2] + 0.5, cy=K[1, 2] + 0.5,
                                  znear=0.05, zfar=100.0)
        world_T_cam = np.eye(4)
        world_T_cam[:3, :3] = camera.R.T
        world_T_cam[:3, 3] = camera.center
        pose = world_T_cam @ _CV_TO_GL
        scene.add(cam, pose=pose)
        scene.add(pr.DirectionalLight(color=np.ones(3), intensity=2.5), pose=pose)
        color, depth = self._renderer.render(scene)
        color, depth = np.ascontiguousarray(color[..., :3]), depth.astype(np.float32)
        if camera.has_distortion:
            color, depth = distort_image(camera, color), distort_image(camera, depth, nearest=True)
        return color, depth


def distort_image(camera: Camera, image: np.ndarray, nearest: bool = False) -> np.ndarray:
    """Turn an ideal pinhole image of ``camera`` into the image of its distorted lens:
    each output pixel samples the pinhole image where its undistorted position falls."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=np.float64),
                       np.arange(camera.height, dtype=np.float64))
    und = undistort_points(camera, np.stack([u.ravel(), v.ravel()], axis=1))
    maps = und.reshape(camera.height, camera.width, 2).astype(np.float32)
    return cv2.remap(image, maps[..., 0], maps[..., 1],
                     cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def body_texture(part_labels: np.ndarray, joint_names: Sequence[str], seed: int = 0) -> np.ndarray:
    """Per-vertex colours (V, 3) uint8: skin, shirt, trousers and shoes by body part, with
    high-frequency noise so that SIFT finds features on the body."""
    rng = np.random.default_rng(seed)
    skin, shirt, trousers, shoes = (np.array(c, float) for c in
                                    ([205, 160, 135], [40, 90, 170], [70, 60, 50], [30, 30, 30]))
    region = {"head": skin, "neck": skin, "l_wrist": skin, "r_wrist": skin,
              "l_elbow": skin, "r_elbow": skin, "l_ankle": shoes, "r_ankle": shoes,
              "pelvis": trousers, "l_hip": trousers, "r_hip": trousers,
              "l_knee": trousers, "r_knee": trousers}
    base = np.stack([region.get(joint_names[j], shirt) for j in part_labels])
    noise = rng.uniform(-55, 55, size=(len(base), 1)) + rng.normal(0, 12, size=base.shape)
    return np.clip(base + noise, 0, 255).astype(np.uint8)


def marker_meshes(points: np.ndarray, color=(40, 230, 40), radius: float = 0.02) -> list[RenderMesh]:
    """Small coloured spheres at marker positions (L, 3)."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    col = np.tile(np.asarray(color, np.uint8), (len(sphere.vertices), 1))
    return [RenderMesh(sphere.vertices + p, sphere.faces, col) for p in points]
