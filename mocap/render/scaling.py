"""Internal-resolution helpers: render at ``scale`` times the camera image size.

Pixel convention (OpenCV): pixel ``(row i, col j)`` has its centre at image coordinates
``(x=j, y=i)`` and covers ``[j - 0.5, j + 0.5] x [i - 0.5, i + 0.5]``; the image of width
``W`` spans ``x`` in ``[-0.5, W - 0.5]``.

Scaling maps that extent onto the extent of the smaller image exactly, so pixel *edges*
(not centres) line up: ``x' = (x + 0.5) * sx - 0.5`` with ``sx = W' / W`` and
``W' = round(W * scale)`` (likewise ``y`` with ``sy = H' / H``). ``sx`` and ``sy`` differ
from ``scale`` only by rounding of the internal size.
"""

from __future__ import annotations

import numpy as np


def scaled_size(height: int, width: int, scale: float) -> tuple[int, int]:
    """Internal image size ``(round(height * scale), round(width * scale))``, at least 1."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive finite number, got {scale}")
    if height <= 0 or width <= 0:
        raise ValueError(f"height and width must be positive, got {height}x{width}")
    return max(1, round(height * scale)), max(1, round(width * scale))


def scale_pixels(pixels: np.ndarray, height: int, width: int,
                 scale: float) -> tuple[np.ndarray, tuple[int, int]]:
    """Pixel coordinates in a ``height x width`` image -> coordinates in the internal image.

    pixels: (..., 2) as (x, y). Returns ``(scaled pixels (..., 2), (H', W'))``; the dtype is
    kept for floating input. ``scale == 1`` returns the input unchanged.
    """
    h2, w2 = scaled_size(height, width, scale)
    pixels = np.asarray(pixels)
    if h2 == height and w2 == width:
        return pixels, (h2, w2)
    dtype = np.dtype(pixels.dtype if np.issubdtype(pixels.dtype, np.floating) else np.float64)
    s = np.array([w2 / width, h2 / height], dtype=dtype)
    return (pixels.astype(dtype, copy=False) + dtype.type(0.5)) * s - dtype.type(0.5), (h2, w2)
