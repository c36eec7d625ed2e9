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

from collections.abc import Callable, Sequence

import numpy as np

from mocap.cameras import Rig
from mocap.energy.markers import HAVE_NUMBA, MarkerObservation, associate, pinhole_project
from mocap.trackers.markers.settings import Refinement  # noqa: F401  (re-exported: its settings)


def refine_pose(points: Callable[[np.ndarray], np.ndarray], chi0: np.ndarray, obs: MarkerObservation,
                rig: Rig, limits: np.ndarray, settings: Refinement,
                gate_px: float) -> tuple[np.ndarray, dict]:
    """chi (D,) refined from chi0; points: (P, D) -> (P, L, 3) landmarks; rig: undistorted
    cameras; limits: (D, 2). Returns (chi, {"iterations", "residual_px" before/after})."""
    chi0 = np.asarray(chi0, np.float64)[None]
    return refine_people([points], chi0, [obs], rig, limits, settings, gate_px)[0]


def refine_people(points: Sequence[Callable[[np.ndarray], np.ndarray]], chi0: np.ndarray,
                  obs: Sequence[MarkerObservation], rig: Rig, limits: np.ndarray, settings: Refinement,
                  gate_px: float) -> list[tuple[np.ndarray, dict]]:
    """:func:`refine_pose` of T people at once: chi0 (T, D), points[n] and obs[n] person n's.
    Each person's steps are its own (the same numbers as refining it alone); the people's
    finite-difference poses are projected in one call and their normal equations solved in
    one batched call. Returns [(chi (D,), info)] per person."""
    s = settings
    gate = s.gate_px or gate_px
    chi0 = np.asarray(chi0, np.float64)
    chi = chi0.copy()
    T, D = chi.shape
    prior = np.full(D, 1.0 / s.prior_std**2)
    infos = [{"residual_px_before": np.nan, "residual_px_after": np.nan, "iterations": 0} for _ in range(T)]
    live = list(range(T))
    for it in range(s.iterations):
        if not live:
            break
        batch = np.repeat(chi[live][:, None], D + 1, axis=1)                # (T', D + 1, D)
        batch[:, 1:] += np.eye(D) * s.step
        u, depth = _project_each(rig, [points[n](b) for n, b in zip(live, batch, strict=True)])
        going, A, g = [], [], []
        for j, n in enumerate(live):
            z, conf, ok = associate(u[j][0], depth[j][0] > 0.05, obs[n], gate, compiled=HAVE_NUMBA)
            if ok.sum() < 3:
                continue
            r = (u[j][0] - z)[ok]                                            # (M, 2)
            J = ((u[j][1:] - u[j][0]) / s.step)[:, ok]                       # (D, M, 2)
            norm = np.linalg.norm(r, axis=1)
            if it == 0:
                infos[n]["residual_px_before"] = float(np.median(norm))
            w = np.where(norm <= s.huber_px, 1.0, s.huber_px / np.maximum(norm, 1e-12))
            if s.use_confidence:
                w = w * conf[ok]
            if s.outlier_views:
                w = w * view_weights(norm, np.nonzero(ok)[1], ok.shape[1], s.outlier_views, s.huber_px)
            Jf = J.transpose(1, 2, 0).reshape(-1, D)                         # (2M, D)
            wf = np.repeat(w, 2)
            rf = r.reshape(-1)
            An = Jf.T @ (wf[:, None] * Jf) + np.diag(prior)
            An[np.diag_indices(D)] *= 1.0 + s.damping
            going.append(n)
            A.append(An)
            g.append(Jf.T @ (wf * rf) + prior * (chi[n] - chi0[n]))
        if going:
            steps = np.linalg.solve(np.stack(A), -np.stack(g)[..., None])[..., 0]
            for n, step in zip(going, steps, strict=True):
                chi[n] = np.clip(chi[n] + step, limits[:, 0], limits[:, 1])
                infos[n]["iterations"] = it + 1
        live = going
    done = [n for n in range(T) if infos[n]["iterations"]]
    if done:
        u, depth = _project_each(rig, [points[n](chi[n][None]) for n in done])
        for j, n in enumerate(done):
            z, _, ok = associate(u[j][0], depth[j][0] > 0.05, obs[n], gate, compiled=HAVE_NUMBA)
            if ok.any():
                infos[n]["residual_px_after"] = float(np.median(np.linalg.norm((u[j][0] - z)[ok], axis=1)))
    return [(chi[n], infos[n]) for n in range(T)]


def _project_each(rig: Rig, points: list[np.ndarray]) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """:func:`pinhole_project` of each of several landmark batches (P, L, 3): one call for
    all of them where the compiled projection (point by point, the same numbers) applies."""
    if HAVE_NUMBA and all(X.dtype == np.float64 and X.shape == points[0].shape for X in points):
        u, depth = pinhole_project(rig, np.stack(points))
        return list(u), list(depth)
    out = [pinhole_project(rig, X) for X in points]
    return [o[0] for o in out], [o[1] for o in out]


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
