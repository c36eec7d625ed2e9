"""Bundle adjustment: camera poses and 3D structure refined together by
``scipy.optimize.least_squares`` with a sparse Jacobian (``jac_sparsity``) and a robust loss.

Two kinds of structure:

* free points (:func:`adjust_points`): every 3D point its own 3 parameters (keypoints of people,
  points of known coordinates held fixed);
* rigid boards (:func:`adjust_boards`): a board's corners move with its pose (6 parameters per
  board pose, one per frame it was seen in).

A camera pose is (rvec (3,), t (3,)) world-to-camera (``x_cam = R(rvec) x + t``); intrinsics
are held fixed. Residuals are pixels (with distortion), times the observations' weights.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from mocap.cameras import rotation_from_rodrigues
from mocap.cameras.projection import distort_normalized


@dataclass(frozen=True)
class BundleSettings:
    """loss / f_scale: scipy's robust loss and its scale (px); max_nfev: evaluations;
    tol: ftol = xtol = gtol."""

    loss: str = "soft_l1"
    f_scale: float = 2.0
    max_nfev: int = 200
    tol: float = 1e-10


def project_points(rvec: np.ndarray, t: np.ndarray, X: np.ndarray, K: np.ndarray,
                   dist: np.ndarray) -> np.ndarray:
    """Per-row projection: rvec, t, X (M, 3); K (M, 3, 3); dist (M, 5) -> pixels (M, 2)
    (points behind the camera project through a clamped depth of 1e-6)."""
    Xc = np.einsum("mij,mj->mi", rotation_from_rodrigues(rvec), X) + t
    z = np.maximum(Xc[:, 2:3], 1e-6)
    xy = distort_normalized(Xc[:, :2] / z, dist)
    return np.stack([K[:, 0, 0] * xy[:, 0] + K[:, 0, 1] * xy[:, 1] + K[:, 0, 2],
                     K[:, 1, 1] * xy[:, 1] + K[:, 1, 2]], -1)


def compose(rvec_a: np.ndarray, t_a: np.ndarray, rvec_b: np.ndarray, t_b: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Pose a after pose b (x -> R_a (R_b x + t_b) + t_a), rows (M, 3) -> (R (M, 3, 3), t (M, 3))."""
    Ra, Rb = rotation_from_rodrigues(rvec_a), rotation_from_rodrigues(rvec_b)
    return Ra @ Rb, np.einsum("mij,mj->mi", Ra, t_b) + t_a


def _sparsity(n_obs: int, blocks: list[tuple[np.ndarray, int, int]], n_params: int) -> csr_matrix:
    """Jacobian pattern: residual rows 2m, 2m+1 depend on, per (index (M,), offset, width) block,
    parameters offset + width * index[m] ... + width - 1 (index -1: none)."""
    rows, cols = [], []
    m = np.arange(n_obs)
    for index, offset, width in blocks:
        ok = index >= 0
        c = offset + width * index[ok][:, None] + np.arange(width)            # (M', width)
        for r in (2 * m[ok], 2 * m[ok] + 1):
            rows.append(np.repeat(r, width))
            cols.append(c.ravel())
    rows_, cols_ = np.concatenate(rows), np.concatenate(cols)
    return csr_matrix((np.ones(len(rows_), np.int8), (rows_, cols_)), shape=(2 * n_obs, n_params))


@dataclass(frozen=True)
class BundleResult:
    """cams (C, 6) rvec | t; structure: points (P, 3) or board poses (B, 6); residuals (M, 2)
    px (unweighted); cost and nfev from least_squares."""

    cams: np.ndarray
    structure: np.ndarray
    residuals: np.ndarray
    cost: float
    nfev: int


def adjust_points(cams: np.ndarray, points: np.ndarray, K: np.ndarray, dist: np.ndarray,
                  obs_cam: np.ndarray, obs_point: np.ndarray, obs_xy: np.ndarray,
                  weights: np.ndarray | None = None, fixed_cams: np.ndarray | None = None,
                  fixed_points: np.ndarray | None = None,
                  settings: BundleSettings = BundleSettings()) -> BundleResult:
    """cams (C, 6) initial poses; points (P, 3); K (C, 3, 3); dist (C, 5); observations: camera
    (M,), point (M,), pixels (M, 2), weights (M,) (None: 1); fixed_cams (C,) / fixed_points (P,)
    bool: held at their initial values."""
    C, P = len(cams), len(points)
    fc = np.zeros(C, bool) if fixed_cams is None else np.asarray(fixed_cams, bool)
    fp = np.zeros(P, bool) if fixed_points is None else np.asarray(fixed_points, bool)
    w = np.ones(len(obs_cam)) if weights is None else np.asarray(weights, float)
    cam_slot = np.full(C, -1)
    cam_slot[~fc] = np.arange((~fc).sum())
    pt_slot = np.full(P, -1)
    pt_slot[~fp] = np.arange((~fp).sum())
    nc = 6 * int((~fc).sum())
    Kc, dc = K[obs_cam], dist[obs_cam]

    def unpack(x):
        c = cams.copy()
        c[~fc] = x[:nc].reshape(-1, 6)
        p = points.copy()
        p[~fp] = x[nc:].reshape(-1, 3)
        return c, p

    def residuals(x):
        c, p = unpack(x)
        uv = project_points(c[obs_cam, :3], c[obs_cam, 3:], p[obs_point], Kc, dc)
        return ((uv - obs_xy) * w[:, None]).ravel()

    x0 = np.concatenate([cams[~fc].ravel(), points[~fp].ravel()])
    A = _sparsity(len(obs_cam), [(cam_slot[obs_cam], 0, 6), (pt_slot[obs_point], nc, 3)], len(x0))
    sol = least_squares(residuals, x0, jac_sparsity=A, method="trf", loss=settings.loss,
                        f_scale=settings.f_scale, x_scale="jac", max_nfev=settings.max_nfev,
                        ftol=settings.tol, xtol=settings.tol, gtol=settings.tol)
    c, p = unpack(sol.x)
    uv = project_points(c[obs_cam, :3], c[obs_cam, 3:], p[obs_point], Kc, dc)
    return BundleResult(c, p, uv - obs_xy, float(sol.cost), int(sol.nfev))


def adjust_boards(cams: np.ndarray, boards: np.ndarray, K: np.ndarray, dist: np.ndarray,
                  obs_cam: np.ndarray, obs_board: np.ndarray, obs_object: np.ndarray,
                  obs_xy: np.ndarray, fixed_cams: np.ndarray | None = None,
                  settings: BundleSettings = BundleSettings()) -> BundleResult:
    """cams (C, 6); boards (B, 6) board-to-world poses; observations: camera (M,), board pose
    (M,), the corner's board coordinates (M, 3), pixels (M, 2)."""
    C = len(cams)
    fc = np.zeros(C, bool) if fixed_cams is None else np.asarray(fixed_cams, bool)
    cam_slot = np.full(C, -1)
    cam_slot[~fc] = np.arange((~fc).sum())
    nc = 6 * int((~fc).sum())
    Kc, dc = K[obs_cam], dist[obs_cam]

    def unpack(x):
        c = cams.copy()
        c[~fc] = x[:nc].reshape(-1, 6)
        return c, x[nc:].reshape(-1, 6)

    def predict(c, b):
        Rb = rotation_from_rodrigues(b[obs_board, :3])
        X = np.einsum("mij,mj->mi", Rb, obs_object) + b[obs_board, 3:]
        return project_points(c[obs_cam, :3], c[obs_cam, 3:], X, Kc, dc)

    def residuals(x):
        return (predict(*unpack(x)) - obs_xy).ravel()

    x0 = np.concatenate([cams[~fc].ravel(), boards.ravel()])
    A = _sparsity(len(obs_cam), [(cam_slot[obs_cam], 0, 6), (obs_board, nc, 6)], len(x0))
    sol = least_squares(residuals, x0, jac_sparsity=A, method="trf", loss=settings.loss,
                        f_scale=settings.f_scale, x_scale="jac", max_nfev=settings.max_nfev,
                        ftol=settings.tol, xtol=settings.tol, gtol=settings.tol)
    c, b = unpack(sol.x)
    return BundleResult(c, b, predict(c, b) - obs_xy, float(sol.cost), int(sol.nfev))
