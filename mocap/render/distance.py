"""Euclidean distance transforms of silhouette masks (``cv2.distanceTransform``).

``DIST_MASK_PRECISE`` is the exact Euclidean distance (matches
``scipy.ndimage.distance_transform_edt`` to 1e-5 px); the 3x3 and 5x5 chamfer masks are
not much faster here (250 px: 0.33 / 0.38 / 0.64 ms per image with OpenCV's own 2 threads)
but are off by up to 5.4 / 2.3 px, so only the exact one is offered.

The same mask gives the same distances whatever OpenCV's thread count: OpenCV (5.0) hands
``DIST_MASK_PRECISE`` to Intel IPP only when it runs on one thread (``cv2.setNumThreads(0 or
1)``) or for images under 2^14 pixels, and IPP's float32 result differs from OpenCV's own by up
to 2e-6 px, which a tracker's search can turn into another track. :func:`distance_transform`
therefore switches IPP off around its calls (``cv2.ipp.setUseIPP`` is per thread): OpenCV's own
transform, one row and one column at a time whatever the threads, as fast here (0.46 ms at
256², 8.4 ms at 1004² against IPP's 0.56 / 9.7 ms on one thread).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np


def distance_transform(mask: np.ndarray, *, empty_value: float = np.inf, threads: int = 1,
                       out: np.ndarray | None = None) -> np.ndarray:
    """Distance from each pixel centre to the nearest silhouette pixel centre.

    mask: (..., H, W) bool or integer, nonzero = silhouette. Returns float32 (..., H, W),
    0 on the silhouette. A mask with no silhouette pixel gives ``empty_value`` everywhere
    (OpenCV would return 65536). threads: images are split over this many threads (OpenCV
    releases the GIL; it also runs its own threads inside each image).
    out: optional C-contiguous float32 array (..., H, W) to write into.
    """
    mask = np.asarray(mask)
    if mask.ndim < 2 or mask.shape[-1] == 0 or mask.shape[-2] == 0:
        raise ValueError(f"mask must have shape (..., H, W) with H, W > 0, got {mask.shape}")
    if not (mask.dtype == bool or np.issubdtype(mask.dtype, np.integer)):
        raise ValueError(f"mask must be bool or integer, got dtype {mask.dtype}")
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads}")
    h, w = mask.shape[-2:]
    background = (mask.reshape(-1, h, w) == 0).view(np.uint8)   # cv2: distance to nearest 0
    if out is None:
        out = np.empty(mask.shape, dtype=np.float32)
    elif out.shape != mask.shape or out.dtype != np.float32 or not out.flags.c_contiguous:
        raise ValueError(f"out must be a C-contiguous float32 array of shape {mask.shape}, "
                         f"got {out.dtype} {out.shape}")
    flat = out.reshape(background.shape)

    def run(ks: range) -> None:
        ipp = cv2.ipp.useIPP()
        cv2.ipp.setUseIPP(False)        # this thread only: the same result on any thread count
        try:
            for k in ks:
                if background[k].all():
                    flat[k] = empty_value
                else:
                    cv2.distanceTransform(background[k], cv2.DIST_L2, cv2.DIST_MASK_PRECISE,
                                          dst=flat[k])
        finally:
            cv2.ipp.setUseIPP(ipp)

    n = len(flat)
    if threads == 1 or n == 1:
        run(range(n))
    else:
        step = -(-n // threads)
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(run, [range(s, min(s + step, n)) for s in range(0, n, step)]))
    return out
