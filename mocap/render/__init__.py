"""Silhouette rasterization and distance transforms (numpy / OpenCV, no GL).

API:
    rasterize_silhouettes(pixels, faces, height, width, depth=None, *, near, scale, method,
                          threads, out) -> bool masks (P, C, H', W')
    SilhouetteRasterizer(faces, num_vertices)(pixels, height, width, depth=None, ...)
    distance_transform(mask, *, empty_value, threads, out) -> float32 distances (..., H, W)
    scaled_size(height, width, scale), scale_pixels(pixels, height, width, scale)
"""

from mocap.render.distance import distance_transform
from mocap.render.scaling import scale_pixels, scaled_size
from mocap.render.silhouette import (
    METHODS,
    SilhouetteRasterizer,
    get_rasterizer,
    rasterize_silhouettes,
)

__all__ = [
    "METHODS", "SilhouetteRasterizer", "distance_transform", "get_rasterizer",
    "rasterize_silhouettes", "scale_pixels", "scaled_size",
]
