"""Initialisation of the marker tracker from one frame of labelled detections
(Canton-Ferrer et al. 2010, Sec. 3.1): triangulate the markers robustly, fit the body's size
to the measured bone lengths, and place a neutral pose at the measured position and heading.

The paper scales the limbs from the subject's height; our body has a PCA shape space, so
the shape coefficients are fitted to the lengths of every landmark pair that no pose can
change (:func:`mocap.body.catalogue.rigid_pairs`). The paper takes the heading
from the direction of motion; with a single frame we take it from the torso landmarks
(a rotation about the vertical fitted to those rigidly attached to the root).
"""

from __future__ import annotations

import itertools

import numpy as np

from mocap.body.bone_lengths import length_model, shrink_to_bounds, skeleton_length_model
from mocap.body.catalogue import probe_poses, rest_point_basis, rigid_pairs
from mocap.body.landmarks import LandmarkSet
from mocap.body.model import BodyModel
from mocap.body.twists import se3_log
from mocap.cameras import Rig, triangulate
from mocap.energy.markers import MarkerObservation, pinhole_project


def pinhole_rig(rig: Rig) -> Rig:
    """The rig without lens distortion (for undistorted pixels)."""
    return Rig(tuple(c.replace(dist=np.zeros(5)) for c in rig))


def triangulate_candidates(rig: Rig, obs: MarkerObservation, gate_px: float,
                           min_views: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Robust triangulation of every landmark from its candidates (a small RANSAC).

    rig: cameras for undistorted pixels (:func:`pinhole_rig`); obs: arranged detections.
    Every pair of candidates in two views is a hypothesis; the one whose projection has a
    candidate within ``gate_px`` in the most views (then the smallest error) wins and is
    re-triangulated from those inliers. Returns points (L, 3) world metres (NaN where fewer
    than ``min_views`` views agree) and the inlier count (L,).
    """
    L, C, K, _ = obs.xy.shape
    points = np.full((L, 3), np.nan)
    count = np.zeros(L, np.int64)
    for lm in range(L):
        cand = [(c, k) for c in range(C) for k in range(K) if obs.valid[lm, c, k]]
        hyps = [(p, q) for p, q in itertools.combinations(cand, 2) if p[0] != q[0]]
        if not hyps:
            continue
        px = np.full((C, len(hyps), 2), np.nan)
        for n, ((a, i), (b, j)) in enumerate(hyps):
            px[a, n], px[b, n] = obs.xy[lm, a, i], obs.xy[lm, b, j]
        X = triangulate(rig, px)                                          # (N, 3)
        ok = np.all(np.isfinite(X), axis=1)
        if not ok.any():
            continue
        u, depth = pinhole_project(rig, np.where(ok[:, None], X, 0.0))    # (N, C, 2), (N, C)
        d2 = ((obs.xy[lm][None] - u[:, :, None, :]) ** 2).sum(-1)         # (N, C, K)
        d2 = np.where(obs.valid[lm][None], d2, np.inf)
        best = d2.min(axis=2)
        inl = (best < gate_px**2) & (depth > 0) & ok[:, None]
        score = inl.sum(axis=1) - np.where(inl, best, 0.0).sum(axis=1) / (C * gate_px**2 + 1e-9)
        n = int(np.argmax(score))
        if inl[n].sum() < min_views:
            continue
        k = np.argmin(d2[n], axis=1)
        px1 = obs.xy[lm, np.arange(C), k]
        points[lm] = triangulate(rig, px1[:, None], valid=inl[n][:, None])[0]
        count[lm] = int(inl[n].sum())
    return points, count


def fit_shape(rest0: np.ndarray, basis: np.ndarray, pairs: np.ndarray, lengths: np.ndarray,
              length_sigma: float = 0.02, iterations: int = 10, prior_mean: np.ndarray | None = None,
              prior_std: float = 1.0) -> np.ndarray:
    """Shape alpha (K,) whose rest landmarks R0 + sum_k alpha_k B_k (rest0: (L, 3), basis:
    (K, L, 3)) have the measured distances ``lengths`` (B,) between ``pairs`` (B, 2); NaN
    lengths are ignored. Gauss-Newton on sum (|R_i - R_j| - l_ij)^2 / sigma^2 +
    |alpha - mu|^2 / s^2: by default mu = 0, s = 1, the standard normal prior of the
    standardised coefficients; the two-cue hybrid centres it on the silhouettes' shape
    (``prior_mean`` mu (K,), ``prior_std`` s)."""
    K = basis.shape[0]
    ok = np.isfinite(lengths)
    pairs, lengths = pairs[ok], lengths[ok]
    mu = np.zeros(K) if prior_mean is None else np.asarray(prior_mean, np.float64)
    alpha = mu.copy()
    if not len(pairs):
        return alpha
    i, j = pairs[:, 0], pairs[:, 1]
    weight = np.full(len(pairs), 1.0 / length_sigma)
    dB = basis[:, i] - basis[:, j]                                        # (K, B, 3)
    for _ in range(iterations):
        R = rest0 + np.einsum("k,klc->lc", alpha, basis)
        v = R[i] - R[j]
        n = np.linalg.norm(v, axis=1)
        r = (n - lengths) * weight
        J = np.einsum("bc,kbc->bk", v / n[:, None], dB) * weight[:, None]   # (B, K)
        A = J.T @ J + np.eye(K) / prior_std**2
        step = np.linalg.solve(A, -(J.T @ r + (alpha - mu) / prior_std**2))
        alpha = alpha + step
        if np.abs(step).max() < 1e-6:
            break
    return alpha


def shape_from_landmarks(body: BodyModel, landmarks: LandmarkSet, measured: np.ndarray,
                         length_sigma: float, outlier_sigma: float, bound_sigma: float,
                         prior_mean: np.ndarray | None = None,
                         prior_std: float = 1.0) -> tuple[np.ndarray, str | None]:
    """The shape alpha (K,) fitted to the distances between measured landmarks (L, 3) world
    metres (NaN: unmeasured) that no pose can change (:func:`mocap.body.catalogue.rigid_pairs`),
    by :func:`fit_shape` (prior N(``prior_mean``, ``prior_std``^2), default the model's N(0, I)).
    Distances more than ``outlier_sigma`` shape-model sigmas from their mean are ignored; a
    fitted body with a bone outside +-``bound_sigma`` sigma is shrunk towards the mean shape
    until every bone is inside, and the second value says so (None: not shrunk)."""
    rest0, basis = rest_point_basis(body, landmarks)
    pairs = rigid_pairs(body, landmarks)
    pair_model = length_model(rest0, basis, pairs)
    lengths = pair_model.lengths(measured)
    lengths[np.abs(pair_model.z_scores(lengths)) > outlier_sigma] = np.nan
    alpha = fit_shape(rest0, basis, pairs, lengths, length_sigma, prior_mean=prior_mean, prior_std=prior_std)
    bones, bone_names = skeleton_length_model(body)
    _, joints = body.rest(alpha[None])
    z = bones.z_scores(bones.lengths(np.asarray(joints[0], np.float64)))
    if np.abs(z).max() <= bound_sigma:
        return alpha, None
    worst = int(np.argmax(np.abs(z)))
    alpha, scale = shrink_to_bounds(body, alpha, bones, bound_sigma)
    return alpha, (f"fitted shape beyond the model's bounds ({bone_names[worst]} at {z[worst]:+.1f} "
                   f"sigma), shrunk towards the mean by {scale:.2f} to +-{bound_sigma:g} sigma")


def root_rigid(body: BodyModel, landmarks: LandmarkSet, tolerance: float = 1e-4) -> np.ndarray:
    """(L,) bool: landmarks that no joint angle moves relative to the root."""
    shaped = body.shaped(np.zeros(body.num_shape))
    chi = np.vstack([np.zeros(body.num_dofs), probe_poses(body)])
    X = landmarks.positions(shaped, chi)
    return np.ptp(X, axis=0).max(axis=1) < tolerance


def yaw_alignment(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray]:
    """Rotation about world z (angle, radians) and translation (3,) that best map points
    src (N, 3) onto dst (N, 3) in the least-squares sense (closed form)."""
    a = src - src.mean(axis=0)
    b = dst - dst.mean(axis=0)
    psi = float(np.arctan2((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum(),
                           (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]).sum()))
    R = rot_z(psi)
    return psi, dst.mean(axis=0) - R @ src.mean(axis=0)


def rot_z(psi: float) -> np.ndarray:
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def neutral_pose(body: BodyModel, rest_points: np.ndarray, measured: np.ndarray,
                 rigid: np.ndarray) -> np.ndarray:
    """Pose chi (D,): joint angles zero (the rest pose), the root rotated about z and moved
    so that the rest landmarks best match the measured ones (L, 3; NaN = unmeasured).
    Uses the root-rigid landmarks (``rigid`` (L,) bool) when two or more are measured,
    else all measured ones."""
    have = np.all(np.isfinite(measured), axis=1)
    use = have & rigid if (have & rigid).sum() >= 2 else have
    chi = np.zeros(body.num_dofs)
    if use.sum() == 0:
        return chi
    if use.sum() == 1:
        psi, t = 0.0, measured[use][0] - rest_points[use][0]
    else:
        psi, t = yaw_alignment(rest_points[use], measured[use])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rot_z(psi), t
    chi[:6] = se3_log(T[None])[0]
    return chi
