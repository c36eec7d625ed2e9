"""Per-frame refinement of the marker tracker's estimate: a few Gauss-Newton (Levenberg-
Marquardt) steps on the reprojection error, starting from the annealed particle filter's
estimate.

The APF's weighted mean is a smoothed, slightly biased estimate (a finite particle set,
diffusion, truncated costs); near the optimum the likelihood is a plain least-squares
problem. Each landmark is associated, in each view, with the candidate nearest to its
projection within ``gate_px`` (re-associated every iteration); residuals are the pixel
offsets u_lc(chi) - z_lc, weighted by the detection's confidence (``use_confidence``) and
robustly by Huber's weights with scale ``huber_px``; a view whose median residual is more
than ``outlier_views`` times the median over the views (and above ``huber_px``) is an outlier
view (a left/right swap, another person's limbs): its weights are scaled by
(``outlier_views`` x median / its median)^2. The Jacobian is taken by forward
differences in one batch of D + 1 poses through the (compiled) landmark kinematics; a
Gaussian prior of width ``prior_std`` (radians / twist units) keeps the pose near the APF
estimate where the detections say little; joint limits are enforced by clipping.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mocap.cameras import Rig
from mocap.energy.markers import HAVE_NUMBA, MarkerObservation, associate, pinhole_project
from mocap.trackers.markers.settings import Refinement  # noqa: F401  (re-exported: its settings)


def refine_pose(points: Callable[[np.ndarray], np.ndarray], chi0: np.ndarray, obs: MarkerObservation,
                rig: Rig, limits: np.ndarray, settings: Refinement,
                gate_px: float) -> tuple[np.ndarray, dict]:
    """chi (D,) refined from chi0; points: (P, D) -> (P, L, 3) landmarks; rig: undistorted
    cameras; limits: (D, 2). Returns (chi, {"iterations", "residual_px" before/after})."""
    s = settings
    gate = s.gate_px or gate_px
    chi = np.asarray(chi0, np.float64).copy()
    D = chi.size
    prior = np.full(D, 1.0 / s.prior_std**2)
    info = {"residual_px_before": np.nan, "residual_px_after": np.nan, "iterations": 0}
    for it in range(s.iterations):
        batch = np.repeat(chi[None], D + 1, axis=0)
        batch[1:] += np.eye(D) * s.step
        X = points(batch)                                            # (D + 1, L, 3)
        u, depth = pinhole_project(rig, X)                           # (D + 1, L, C, 2)
        z, conf, ok = associate(u[0], depth[0] > 0.05, obs, gate, compiled=HAVE_NUMBA)
        if ok.sum() < 3:
            break
        r = (u[0] - z)[ok]                                           # (M, 2)
        J = ((u[1:] - u[0]) / s.step)[:, ok]                         # (D, M, 2)
        norm = np.linalg.norm(r, axis=1)
        if it == 0:
            info["residual_px_before"] = float(np.median(norm))
        w = np.where(norm <= s.huber_px, 1.0, s.huber_px / np.maximum(norm, 1e-12))
        if s.use_confidence:
            w = w * conf[ok]
        if s.outlier_views:
            w = w * view_weights(norm, np.nonzero(ok)[1], ok.shape[1], s.outlier_views, s.huber_px)
        Jf = J.transpose(1, 2, 0).reshape(-1, D)                     # (2M, D)
        wf = np.repeat(w, 2)
        rf = r.reshape(-1)
        A = Jf.T @ (wf[:, None] * Jf) + np.diag(prior)
        A[np.diag_indices(D)] *= 1.0 + s.damping
        g = Jf.T @ (wf * rf) + prior * (chi - chi0)
        step = np.linalg.solve(A, -g)
        chi = np.clip(chi + step, limits[:, 0], limits[:, 1])
        info["iterations"] = it + 1
    if info["iterations"]:
        X = points(chi[None])
        u, depth = pinhole_project(rig, X)
        z, _, ok = associate(u[0], depth[0] > 0.05, obs, gate, compiled=HAVE_NUMBA)
        if ok.any():
            info["residual_px_after"] = float(np.median(np.linalg.norm((u[0] - z)[ok], axis=1)))
    return chi, info


def view_weights(norm: np.ndarray, view: np.ndarray, views: int, factor: float, floor_px: float,
                 min_count: int = 3) -> np.ndarray:
    """Per-residual weights (M,) that down-weight outlier views: residual norms (M,) px in
    views ``view`` (M,); a view (with ``min_count`` residuals or more) whose median residual m_c
    exceeds ``factor`` x max(median over such views, ``floor_px``) gets (factor x that / m_c)^2,
    the others 1."""
    med = np.full(views, np.nan)
    for c in range(views):
        sel = view == c
        if sel.sum() >= min_count:
            med[c] = np.median(norm[sel])
    if np.isfinite(med).sum() < 3:
        return np.ones_like(norm)
    limit = factor * max(float(np.nanmedian(med)), floor_px)
    wv = np.where(np.isfinite(med) & (med > limit), (limit / np.where(np.isfinite(med), med, 1.0)) ** 2, 1.0)
    return wv[view]
