"""Projection, back-projection, Plücker lines, epipolar geometry and triangulation.

Batch-first and vectorised over points, particles and views. Conventions as in
:mod:`mocap.cameras.camera`: OpenCV camera frame, ``x_cam = R @ x_world + t``, OpenCV
5-coefficient distortion ``(k1, k2, p1, p2, k3)``, pixel centres at integer coordinates.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocap.cameras.camera import Camera, Rig, _skew, as_rig

CameraLike = Camera | Rig | Sequence[Camera]


# --- distortion on normalised image coordinates ---------------------------------------------


def _split_dist(dist: np.ndarray, dtype=np.float64) -> tuple[np.ndarray, ...]:
    d = np.asarray(dist, dtype=dtype)
    return d[..., 0], d[..., 1], d[..., 2], d[..., 3], d[..., 4]


def _distort_xy(x, y, k1, k2, p1, p2, k3):
    """Apply OpenCV's radial + tangential model to normalised coordinates (broadcasting)."""
    x2, y2, xy = x * x, y * y, x * y
    r2 = x2 + y2
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2)
    yd = y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy
    return xd, yd


def distort_normalized(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Distort normalised image coordinates with OpenCV's model.

    xy: (..., 2) undistorted normalised coordinates (x_cam / z, y_cam / z).
    dist: (5,) or (..., 5) broadcastable to xy's leading shape: (k1, k2, p1, p2, k3).
    Returns (..., 2): with r^2 = x^2 + y^2 and L = 1 + k1 r^2 + k2 r^4 + k3 r^6,
    ``x_d = x L + 2 p1 x y + p2 (r^2 + 2 x^2)``, ``y_d = y L + p1 (r^2 + 2 y^2) + 2 p2 x y``.
    """
    xy = np.asarray(xy, dtype=np.float64)
    xd, yd = _distort_xy(xy[..., 0], xy[..., 1], *_split_dist(dist))
    return np.stack([xd, yd], axis=-1)


def undistort_normalized(
    xy_distorted: np.ndarray, dist: np.ndarray, iterations: int = 20, tol: float = 1e-15
) -> np.ndarray:
    """Invert :func:`distort_normalized`: (..., 2) distorted -> (..., 2) undistorted
    normalised coordinates; dist: (5,) or (..., 5) broadcastable.

    A few fixed-point steps (OpenCV's ``undistortPoints`` scheme) followed by Newton steps
    with the analytic 2x2 Jacobian, until the residual is below ``tol`` or ``iterations``
    Newton steps were made. Where the distortion polynomial folds over (far outside the
    calibrated field of view) the inverse is not unique and the result is whatever the
    iteration reached.
    """
    xy_distorted = np.asarray(xy_distorted, dtype=np.float64)
    k1, k2, p1, p2, k3 = _split_dist(dist)
    xd, yd = xy_distorted[..., 0], xy_distorted[..., 1]
    if not (np.any(k1) or np.any(k2) or np.any(p1) or np.any(p2) or np.any(k3)):
        return xy_distorted.copy()
    x, y = xd, yd
    for _ in range(5):  # fixed point: x = (x_d - tangential(x)) / radial(x)
        x2, y2, xy = x * x, y * y, x * y
        r2 = x2 + y2
        inv_radial = 1.0 / (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
        x = (xd - 2.0 * p1 * xy - p2 * (r2 + 2.0 * x2)) * inv_radial
        y = (yd - p1 * (r2 + 2.0 * y2) - 2.0 * p2 * xy) * inv_radial
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(iterations):
            fx, fy = _distort_xy(x, y, k1, k2, p1, p2, k3)
            rx, ry = fx - xd, fy - yd
            if not np.any(np.abs(rx) > tol) and not np.any(np.abs(ry) > tol):
                break
            r2 = x * x + y * y
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # dL / d(r^2)
            jxx = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x
            jyy = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x
            jxy = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y
            det = jxx * jyy - jxy * jxy
            dx = (jyy * rx - jxy * ry) / det
            dy = (jxx * ry - jxy * rx) / det
            ok = np.isfinite(dx) & np.isfinite(dy)
            x = np.where(ok, x - np.where(ok, dx, 0.0), x)
            y = np.where(ok, y - np.where(ok, dy, 0.0), y)
    return np.stack([x, y], axis=-1)


# --- projection ------------------------------------------------------------------------------


def camera_coordinates(rig: Rig, points: np.ndarray) -> np.ndarray:
    """World points (..., N, 3) -> camera coordinates (..., C, 3, N) in every view of ``rig``
    (``R @ x + t``; rows x, y, z contiguous), float32 for float32 points, else float64.

    The first step of :func:`project`; the compiled silhouette energy takes it from here and
    finishes the projection per particle-view with :func:`project`'s arithmetic."""
    pts = np.asarray(points)
    if pts.ndim < 2 or pts.shape[-1] != 3:
        raise ValueError(f"points must have shape (N, 3) or (P, N, 3), got {pts.shape}")
    dtype = np.result_type(pts.dtype, np.float32)
    pts = pts.astype(dtype, copy=False)
    R = rig.R.astype(dtype)
    t = rig.t.astype(dtype)
    # (C, 3, 3) @ (..., 1, 3, N) -> (..., C, 3, N): camera coordinates, rows contiguous.
    X = R @ np.swapaxes(pts, -1, -2)[..., None, :, :]
    X += t[:, :, None]
    return X


def project(
    cameras: CameraLike, points: np.ndarray, return_depth: bool = False
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Project world points into every view, with distortion.

    cameras: a :class:`Rig` (or sequence of C cameras), or one :class:`Camera`.
    points: (N, 3) or (P, N, 3) world metres (any leading batch shape (..., N, 3) works).
    Returns pixels: (C, N, 2) for (N, 3) input, (P, C, N, 2) for (P, N, 3) input; with a
    single Camera the C axis is dropped. With ``return_depth`` also returns depth: the same
    shape without the last axis, z in each camera's frame, metres.

    Pixels of points with depth <= 0 (behind the camera) are meaningless (and NaN/inf at
    depth 0): mask them with the depth. float32 points give float32 results (float64
    otherwise); equals ``cv2.projectPoints`` for float64 input (without skew, which
    projectPoints ignores).
    """
    single = isinstance(cameras, Camera)
    rig = as_rig(cameras)
    pixels, z = pixels_from_camera(rig, camera_coordinates(rig, points), overwrite=True)
    if not return_depth:
        return pixels[..., 0, :, :] if single else pixels
    depth = np.ascontiguousarray(z)  # do not keep the whole (..., C, 3, N) block alive
    return (pixels[..., 0, :, :], depth[..., 0, :]) if single else (pixels, depth)


def pixels_from_camera(rig: Rig, X: np.ndarray, overwrite: bool = False
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Camera coordinates (..., C, 3, N) (:func:`camera_coordinates`) -> pixels
    (..., C, N, 2) and depth (..., C, N) in ``rig``'s views: :func:`project`'s second step,
    for code that has the camera coordinates already (e.g. in a rig and its rescaled copy,
    which share R and t). ``overwrite`` lets it use X's x and y rows as scratch; the depth
    returned is a view of X's z rows (never overwritten)."""
    dtype = X.dtype
    z = X[..., 2, :]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv_z = np.reciprocal(z)
        x = X[..., 0, :] if overwrite else X[..., 0, :].copy()
        x *= inv_z
        y = X[..., 1, :] if overwrite else X[..., 1, :].copy()
        y *= inv_z
        if np.any(rig.dist):
            coeffs = [c[:, None] for c in _split_dist(rig.dist, dtype)]  # each (C, 1)
            x, y = _distort_xy(x, y, *coeffs)
    K = rig.K.astype(dtype)
    pixels = np.empty(X.shape[:-2] + (X.shape[-1], 2), dtype=dtype)
    u, v = pixels[..., 0], pixels[..., 1]
    np.multiply(K[:, 0, 0, None], x, out=u)
    u += K[:, 0, 2, None]
    if np.any(K[:, 0, 1]):
        u += K[:, 0, 1, None] * y
    np.multiply(K[:, 1, 1, None], y, out=v)
    v += K[:, 1, 2, None]
    return pixels, z


# --- back-projection -------------------------------------------------------------------------


def _pixels_per_view(cameras: CameraLike, pixels: np.ndarray) -> tuple[Rig, np.ndarray, bool]:
    """(rig, pixels as (C, M, 2), single-camera flag)."""
    single = isinstance(cameras, Camera)
    rig = as_rig(cameras)
    px = np.asarray(pixels, dtype=np.float64)
    if px.shape[-1:] != (2,):
        raise ValueError(f"pixels must have a last axis of 2, got {px.shape}")
    if single:
        px = px[None]
    if px.ndim < 2 or px.shape[0] != len(rig):
        raise ValueError(f"pixels must have shape (C={len(rig)}, ..., 2), got {px.shape}")
    return rig, px.reshape(len(rig), -1, 2), single


def undistort_points(
    cameras: CameraLike, pixels: np.ndarray, normalized: bool = False
) -> np.ndarray:
    """Remove lens distortion from pixel coordinates.

    cameras: one Camera with pixels (..., 2), or a Rig with pixels (C, ..., 2).
    Returns the same shape: undistorted pixels (same K), or with ``normalized`` the
    normalised image coordinates (x_cam / z, y_cam / z). Iterative inverse, see
    :func:`undistort_normalized`.
    """
    rig, px, single = _pixels_per_view(cameras, pixels)
    shape = np.shape(pixels)
    K = rig.K
    fx, s, cx = K[:, 0, 0, None], K[:, 0, 1, None], K[:, 0, 2, None]
    fy, cy = K[:, 1, 1, None], K[:, 1, 2, None]
    yd = (px[..., 1] - cy) / fy
    xd = (px[..., 0] - cx - s * yd) / fx
    xy = undistort_normalized(np.stack([xd, yd], -1), rig.dist[:, None, :])
    if not normalized:
        x, y = xy[..., 0], xy[..., 1]
        xy = np.stack([fx * x + s * y + cx, fy * y + cy], axis=-1)
    return xy.reshape(shape)


def pixel_rays(cameras: CameraLike, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Back-project pixels to world rays (distortion removed).

    cameras: one Camera with pixels (..., 2), or a Rig with pixels (C, ..., 2).
    Returns (origins, directions), both (..., 3) (resp. (C, ..., 3)) world metres: origins
    are the camera centres, directions unit vectors pointing into the scene (z_cam > 0).
    """
    rig, px, single = _pixels_per_view(cameras, pixels)
    xy = undistort_points(rig, px, normalized=True)  # (C, M, 2)
    d_cam = np.concatenate([xy, np.ones_like(xy[..., :1])], axis=-1)
    d_cam /= np.linalg.norm(d_cam, axis=-1, keepdims=True)
    d_world = d_cam @ rig.R  # row-vector form of R^T d
    origins = np.broadcast_to(rig.centers[:, None, :], d_world.shape)
    out_shape = (() if single else (len(rig),)) + np.shape(pixels)[(0 if single else 1):-1]
    return origins.reshape(*out_shape, 3).copy(), d_world.reshape(*out_shape, 3)


# --- Plücker lines ---------------------------------------------------------------------------


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (3) of broadcastable arrays: ``np.cross``'s products and
    differences, the same floats (tested), without its axis juggling (5x faster on the
    contour matcher's ~12,000 rays per iteration)."""
    a, b = np.asarray(a), np.asarray(b)
    shape = np.broadcast_shapes(a.shape, b.shape)
    out = np.empty(shape, np.result_type(a, b))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


def plucker_from_rays(origin: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plücker coordinates of lines through ``origin`` along ``direction``.

    origin, direction: (..., 3) broadcastable, world metres. Returns (d, m), (..., 3) each:
    d the unit direction, m = origin x d the moment (independent of the point chosen on
    the line).
    """
    direction = np.asarray(direction, dtype=np.float64)
    norm = np.linalg.norm(direction, axis=-1, keepdims=True)
    if np.any(norm == 0):
        raise ValueError("ray directions must be non-zero")
    d = direction / norm
    m = cross3(np.asarray(origin, dtype=np.float64), d)
    return np.broadcast_arrays(d, m)


def point_line_distance(points: np.ndarray, d: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Distance from points to Plücker lines: ``||x × d − m||``.

    points: (..., 3); d: (..., 3) unit directions; m: (..., 3) moments; all broadcastable
    (e.g. points (P, 1, N, 3) against lines (C, N, 3)). Returns the broadcast shape without
    the last axis, metres. Equals the Euclidean point-to-line distance because d is unit.
    """
    x = np.asarray(points)
    return np.linalg.norm(cross3(x, d) - m, axis=-1)


# --- epipolar geometry -----------------------------------------------------------------------


def fundamental_matrix(cam_a: Camera, cam_b: Camera) -> np.ndarray:
    """(3, 3) fundamental matrix F with ``x_b^T F x_a = 0`` for corresponding undistorted
    homogeneous pixels x_a (view a) and x_b (view b); scaled to unit Frobenius norm.

    F = K_b^-T [t_ba]_x R_ba K_a^-1 with R_ba = R_b R_a^T, t_ba = t_b - R_ba t_a.
    """
    R_ba = cam_b.R @ cam_a.R.T
    t_ba = cam_b.t - R_ba @ cam_a.t
    F = np.linalg.inv(cam_b.K).T @ _skew(t_ba) @ R_ba @ np.linalg.inv(cam_a.K)
    norm = np.linalg.norm(F)
    if norm == 0:
        raise ValueError(f"cameras {cam_a.name!r} and {cam_b.name!r} share their centre: "
                         "no epipolar geometry")
    return F / norm


def fundamental_matrices(cameras: CameraLike) -> np.ndarray:
    """(C, C, 3, 3) with ``F[a, b]`` = :func:`fundamental_matrix` (rig[a], rig[b]), i.e.
    ``x_b^T F[a, b] x_a = 0``; ``F[b, a] = F[a, b].T``; the diagonal is zero."""
    rig = as_rig(cameras)
    C = len(rig)
    F = np.zeros((C, C, 3, 3))
    for a in range(C):
        for b in range(a + 1, C):
            F[a, b] = fundamental_matrix(rig[a], rig[b])
            F[b, a] = F[a, b].T
    return F


def epipolar_distance(F: np.ndarray, pixels_a: np.ndarray, pixels_b: np.ndarray) -> np.ndarray:
    """Distance in pixels from x_b to the epipolar line F x_a in view b.

    F: (..., 3, 3); pixels_a, pixels_b: (..., 2) undistorted pixels; broadcastable.
    Returns the broadcast shape without the last axis.
    """
    xa = np.asarray(pixels_a, dtype=np.float64)
    xb = np.asarray(pixels_b, dtype=np.float64)
    xa_h = np.concatenate([xa, np.ones_like(xa[..., :1])], axis=-1)
    lines = np.einsum("...ij,...j->...i", F, xa_h)
    num = lines[..., 0] * xb[..., 0] + lines[..., 1] * xb[..., 1] + lines[..., 2]
    return np.abs(num) / np.hypot(lines[..., 0], lines[..., 1])


# --- triangulation ---------------------------------------------------------------------------


def triangulate(
    cameras: CameraLike,
    pixels: np.ndarray,
    valid: np.ndarray | None = None,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Linear (DLT) triangulation over the views where a point is valid.

    cameras: Rig or sequence of C cameras.
    pixels: (C, N, 2) distorted pixels (any (C, ..., 2) works); distortion is removed first.
    valid: (C, N) bool, None = all; non-finite pixels count as invalid.
    weights: (C, N) optional non-negative weights per observation (e.g. detector
    confidence), multiplying the DLT rows.
    Returns (N, 3) world metres (resp. (..., 3)); NaN where fewer than 2 views are valid.

    Each valid view contributes ``x P3 - P1`` and ``y P3 - P2`` with P = [R | t] and (x, y)
    normalised coordinates, rows scaled to unit norm; the solution is the smallest right
    singular vector.
    """
    rig = as_rig(cameras)
    px = np.asarray(pixels, dtype=np.float64)
    C = len(rig)
    if px.ndim < 2 or px.shape[0] != C or px.shape[-1] != 2:
        raise ValueError(f"pixels must have shape (C={C}, N, 2), got {px.shape}")
    batch = px.shape[1:-1]
    px = px.reshape(C, -1, 2)
    ok = np.all(np.isfinite(px), axis=-1)
    if valid is not None:
        ok &= np.asarray(valid, dtype=bool).reshape(C, -1)
    w = ok.astype(np.float64)
    if weights is not None:
        w = w * np.asarray(weights, dtype=np.float64).reshape(C, -1)
    xy = undistort_points(rig, np.where(ok[..., None], px, 0.0), normalized=True)
    M = np.concatenate([rig.R, rig.t[:, :, None]], axis=2)  # (C, 3, 4)
    rows_x = xy[..., 0, None] * M[:, None, 2] - M[:, None, 0]  # (C, N, 4)
    rows_y = xy[..., 1, None] * M[:, None, 2] - M[:, None, 1]
    A = np.concatenate([rows_x, rows_y], axis=0)  # (2C, N, 4)
    A /= np.linalg.norm(A, axis=-1, keepdims=True)
    A *= np.concatenate([w, w], axis=0)[..., None]
    _, _, vt = np.linalg.svd(np.moveaxis(A, 1, 0), full_matrices=False)  # A: (N, 2C, 4)
    X = vt[:, -1, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        points = X[:, :3] / X[:, 3:]
    points[np.count_nonzero(w > 0, axis=0) < 2] = np.nan
    return points.reshape(*batch, 3)
