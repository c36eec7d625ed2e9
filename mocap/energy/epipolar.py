"""The symmetric epipolar distance and its generalisation to N views (Canton-Ferrer et al.
2010, Sec. 3.3, after their ref. [14]; Hartley & Zisserman 2004, Sec. 11.4.3).

The extracted text of the paper lost the formula, so this module implements the standard
forms and states them exactly. With F_ab the fundamental matrix of views (a, b)
(``x_b^T F_ab x_a = 0``, :func:`mocap.cameras.fundamental_matrices`), x~ = (x, y, 1) an
undistorted pixel and d(x, l) the distance in pixels from a point to an image line,

* symmetric epipolar distance of a point pair (x_a in view a, x_b in view b)::

      d_sym(x_a, x_b)^2 = d(x_b, F_ab x~_a)^2 + d(x_a, F_ab^T x~_b)^2
                        = (x~_b^T F_ab x~_a)^2 (1 / |(F_ab x~_a)_12|^2 + 1 / |(F_ab^T x~_b)_12|^2)

  (|l_12| the norm of a line's first two coefficients). It is zero exactly when the pair
  satisfies the epipolar constraint, and d_sym(F_ab; x_a, x_b) = d_sym(F_ba; x_b, x_a).
* generalised symmetric epipolar distance of a set of points, at most one per view, over
  the set V of views that hold one (|V| >= 2)::

      D(x_V)^2 = 1 / (|V| (|V| - 1) / 2) * sum_{a < b in V} d_sym(x_a, x_b)^2

  the mean squared symmetric distance over all view pairs: zero for exact correspondences
  (projections of one 3D point); for three or more views in general position also only for
  them, whereas with two views any pair on corresponding epipolar lines scores zero, which is
  why markers seen in fewer than three views need the extra care of Sec. 3.4.

All functions are batch-first and broadcast over leading axes; pixels are undistorted.
"""

from __future__ import annotations

import numpy as np


def _homogeneous(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    return np.concatenate([x, np.ones_like(x[..., :1])], axis=-1)


def symmetric_epipolar_sq(F_ab: np.ndarray, x_a: np.ndarray, x_b: np.ndarray,
                          eps: float = 1e-12) -> np.ndarray:
    """Squared symmetric epipolar distance (pixels^2), see the module docstring.

    F_ab: (..., 3, 3) with ``x_b^T F_ab x_a = 0``; x_a, x_b: (..., 2) undistorted pixels;
    all broadcastable. Returns the broadcast shape without the last axis.
    """
    xa, xb = _homogeneous(x_a), _homogeneous(x_b)
    F = np.asarray(F_ab, dtype=np.float64)
    line_b = np.einsum("...ij,...j->...i", F, xa)          # epipolar line of x_a in view b
    line_a = np.einsum("...ji,...j->...i", F, xb)          # F^T x_b: line of x_b in view a
    num = (line_b * xb).sum(axis=-1) ** 2
    return num * (1.0 / np.maximum(line_b[..., 0] ** 2 + line_b[..., 1] ** 2, eps)
                  + 1.0 / np.maximum(line_a[..., 0] ** 2 + line_a[..., 1] ** 2, eps))


def symmetric_epipolar_distance(F_ab: np.ndarray, x_a: np.ndarray, x_b: np.ndarray) -> np.ndarray:
    """Symmetric epipolar distance sqrt(d(x_b, F x_a)^2 + d(x_a, F^T x_b)^2), pixels.

    F_ab: (..., 3, 3); x_a, x_b: (..., 2) undistorted pixels, broadcastable -> (...).
    """
    return np.sqrt(symmetric_epipolar_sq(F_ab, x_a, x_b))


def pairwise_symmetric_sq(F: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Squared symmetric epipolar distances of every ordered view pair.

    F: (C, C, 3, 3) fundamental matrices (``F[a, b]`` maps view a to lines in view b);
    x: (..., C, 2) one undistorted point per view. Returns (..., C, C) pixels^2, symmetric,
    with a zero diagonal.
    """
    C = F.shape[0]
    x = np.asarray(x, dtype=np.float64)
    out = symmetric_epipolar_sq(F, x[..., :, None, :], x[..., None, :, :])
    out[..., np.arange(C), np.arange(C)] = 0.0
    return out


def generalized_symmetric_epipolar_distance(F: np.ndarray, x: np.ndarray,
                                            valid: np.ndarray | None = None) -> np.ndarray:
    """Generalised symmetric epipolar distance D(x_V) of points across C views (pixels).

    F: (C, C, 3, 3); x: (..., C, 2) undistorted pixels, one per view; valid: (..., C) bool,
    the views V that hold a point (None: all). Returns (...): the root mean squared symmetric
    epipolar distance over the pairs of valid views; NaN where fewer than two are valid.
    """
    x = np.asarray(x, dtype=np.float64)
    C = F.shape[0]
    ok = np.ones(x.shape[:-1], bool) if valid is None else np.asarray(valid, bool)
    sq = pairwise_symmetric_sq(F, np.where(ok[..., None], x, 0.0))
    pair = ok[..., :, None] & ok[..., None, :] & ~np.eye(C, dtype=bool)
    n = pair.sum(axis=(-1, -2))
    total = np.where(pair, sq, 0.0).sum(axis=(-1, -2))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(total / np.maximum(n, 1)), np.nan)


def skeleton_epipolar_distance(F_ab: np.ndarray, x_a: np.ndarray, valid_a: np.ndarray,
                               x_b: np.ndarray, valid_b: np.ndarray, min_common: int = 4) -> np.ndarray:
    """Epipolar consistency of whole skeletons: the median, over the landmarks both hold, of
    the symmetric epipolar distance between person i in view a and person j in view b.

    F_ab: (3, 3); x_a: (N, L, 2), valid_a: (N, L); x_b: (M, L, 2), valid_b: (M, L), undistorted
    pixels. Returns (N, M) pixels; inf where fewer than ``min_common`` landmarks are shared.
    A single keypoint pair can agree by chance (any point on the epipolar line does); the
    median over a skeleton's keypoints only for the same person.
    """
    d = symmetric_epipolar_distance(F_ab, x_a[:, None], x_b[None])       # (N, M, L)
    both = valid_a[:, None] & valid_b[None]
    d = np.where(both, d, np.nan)
    out = np.full(both.shape[:2], np.inf)
    enough = both.sum(axis=-1) >= min_common
    if enough.any():
        out[enough] = np.nanmedian(d[enough], axis=-1)
    return out
