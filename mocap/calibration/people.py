"""Extrinsics from the people in the scene: one person's 2D keypoints in every view, matched
across views by frame number and keypoint index, are the correspondences of an uncalibrated
structure-from-motion problem with known intrinsics.

1. pairwise relative poses: ``cv2.findEssentialMat`` (RANSAC) on undistorted normalised points,
   then ``cv2.recoverPose``; the pair with the most inliers starts the reconstruction (first
   camera at the origin, baseline 1);
2. the other cameras join one at a time (the one seeing most reconstructed points first):
   ``cv2.solvePnPRansac`` against the triangulated keypoints, new points triangulated, then a
   bundle adjustment of everything placed so far (:func:`mocap.calibration.bundle.adjust_points`);
3. a final bundle adjustment over all cameras and points with a robust loss, observations
   with a residual above ``outlier_px`` dropped, and once more.

The result is in an arbitrary similarity frame (first camera at the origin, its distance to
the second = 1): :mod:`mocap.calibration.scale_floor` gives it metres and a floor.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np

from mocap.calibration.bundle import BundleSettings, adjust_points
from mocap.calibration.errors import CalibrationInputError


@dataclass(frozen=True)
class PeopleSettings:
    """min_confidence: keypoints below it are not used; min_shared: keypoints two cameras must
    both see to be related (a camera relating to no other is refused); ransac_px: the essential
    matrix's RANSAC threshold (px); outlier_px: final residuals above it are dropped (px)."""

    min_confidence: float = 0.3
    min_shared: int = 50
    ransac_px: float = 4.0
    outlier_px: float = 15.0
    bundle: BundleSettings = BundleSettings(loss="soft_l1", f_scale=3.0, max_nfev=150, tol=1e-8)
    #: evaluations of the bundle adjustments run while cameras are being added
    partial_nfev: int = 30


def normalised(xy: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of one camera -> undistorted normalised coordinates (N, 2)."""
    if len(xy) == 0:
        return np.zeros((0, 2))
    return cv2.undistortPoints(xy.reshape(-1, 1, 2).astype(np.float64), K, dist).reshape(-1, 2)


def triangulate_normalised(R: np.ndarray, t: np.ndarray, xy: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Linear (DLT) triangulation from normalised coordinates. R (C, 3, 3), t (C, 3) world-to-
    camera; xy (C, P, 2); valid (C, P) -> (P, 3), NaN where fewer than 2 views."""
    P34 = np.concatenate([R, t[:, :, None]], axis=2)                       # (C, 3, 4)
    rows = np.concatenate([xy[..., 0:1] * P34[:, None, 2] - P34[:, None, 0],
                           xy[..., 1:2] * P34[:, None, 2] - P34[:, None, 1]], axis=-1)   # (C, P, 8)
    A = rows.reshape(len(R), -1, 2, 4) * valid[:, :, None, None]
    A = np.transpose(A, (1, 0, 2, 3)).reshape(xy.shape[1], -1, 4)           # (P, 2C, 4)
    _, _, Vt = np.linalg.svd(A)
    X = Vt[:, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        X = X[:, :3] / X[:, 3:]
    X[valid.sum(0) < 2] = np.nan
    return X


def shared_counts(valid: np.ndarray) -> np.ndarray:
    """(C, N) bool -> (C, C) keypoints seen by both cameras."""
    v = valid.astype(np.int64)
    return v @ v.T


def check_overlap(names: Sequence[str], valid: np.ndarray, min_shared: int) -> None:
    """Refuse a camera that shares fewer than ``min_shared`` keypoints with every other camera,
    or a rig that falls apart in unconnected groups."""
    S = shared_counts(valid)
    np.fill_diagonal(S, 0)
    for i, n in enumerate(names):
        if S[i].max(initial=0) < min_shared:
            raise CalibrationInputError(
                n, f"sees at most {int(S[i].max(initial=0))} keypoints that another camera also sees "
                   f"(at least {min_shared} needed): no overlap with the other cameras; film the person "
                   "where this camera and another both see them, or leave the camera out")
    seen, todo = {0}, [0]
    while todo:
        i = todo.pop()
        for j in np.flatnonzero(S[i] >= min_shared):
            if j not in seen:
                seen.add(int(j))
                todo.append(int(j))
    if len(seen) < len(names):
        lost = [names[i] for i in range(len(names)) if i not in seen]
        raise CalibrationInputError(lost[0], f"cameras {lost} share no keypoints with camera {names[0]!r}'s "
                                             "group: the rig is in unconnected parts; film a person walking "
                                             "through the views that join them")


@dataclass(frozen=True)
class PeopleResult:
    """cams (C, 6) rvec | t in the reconstruction's frame; points (N, 3) (NaN: not
    reconstructed); used (C, N) observations kept; residuals (C, N, 2) px (NaN: unused);
    pairs: (i, j, inliers) of the essential matrices; order: the cameras as placed."""

    cams: np.ndarray
    points: np.ndarray
    used: np.ndarray
    residuals: np.ndarray
    pairs: list[tuple[int, int, int]]
    order: list[int]


def _bundle(cams, X, K, dist, xy, valid, weight, placed, fixed, settings):
    have = np.isfinite(X).all(1)
    obs = valid & have[None] & placed[:, None]
    c_idx, p_idx = np.nonzero(obs)
    res = adjust_points(cams, np.where(have[:, None], X, 0.0), K, dist, c_idx, p_idx, xy[c_idx, p_idx],
                        weight[c_idx, p_idx], fixed_cams=fixed | ~placed, fixed_points=~have,
                        settings=settings)
    X = np.where(have[:, None], res.structure, np.nan)
    r = np.full(xy.shape, np.nan)
    r[c_idx, p_idx] = res.residuals
    return res.cams, X, r


def calibrate_from_keypoints(names: Sequence[str], K: np.ndarray, dist: np.ndarray, xy: np.ndarray,
                             confidence: np.ndarray, settings: PeopleSettings = PeopleSettings()
                             ) -> PeopleResult:
    """names (C,); K (C, 3, 3), dist (C, 5) intrinsics; xy (C, N, 2) px and confidence (C, N)
    of N keypoint tracks (frame x keypoint, flattened) matched across the views."""
    C, N = confidence.shape
    valid = confidence >= settings.min_confidence
    check_overlap(names, valid, settings.min_shared)
    weight = np.clip(confidence, 0, 1)
    nxy = np.stack([normalised(xy[c], K[c], dist[c]) for c in range(C)])
    focal = K[:, [0, 1], [0, 1]].mean(1)
    pairs = []
    best = None
    for i in range(C):
        for j in range(i + 1, C):
            m = valid[i] & valid[j]
            if m.sum() < settings.min_shared:
                continue
            thr = settings.ransac_px / np.sqrt(focal[i] * focal[j])
            E, mask = cv2.findEssentialMat(nxy[i, m], nxy[j, m], np.eye(3), method=cv2.RANSAC,
                                           prob=0.9999, threshold=thr)
            if E is None:
                continue
            n_in, R, t, mask2 = cv2.recoverPose(E[:3], nxy[i, m], nxy[j, m], np.eye(3), mask=mask)
            pairs.append((i, j, int(n_in)))
            if best is None or n_in > best[2]:
                best = (i, j, int(n_in), R, t.reshape(3))
    if best is None:
        raise CalibrationInputError(names[0], "no pair of cameras gave a relative pose: check that the "
                                              "keypoint folders hold the same person at the same frames")
    a, b, _, R, t = best
    cams = np.zeros((C, 6))
    cams[b, :3] = cv2.Rodrigues(R)[0].reshape(3)
    cams[b, 3:] = t
    placed = np.zeros(C, bool)
    placed[[a, b]] = True
    fixed = np.zeros(C, bool)
    fixed[a] = True
    order = [a, b]

    def tri():
        Rs = np.stack([cv2.Rodrigues(c[:3])[0] for c in cams])
        X = triangulate_normalised(Rs[placed], cams[placed, 3:], nxy[placed], valid[placed])
        # points behind a camera that sees them: not used
        Xc = np.einsum("cij,pj->cpi", Rs[placed], np.nan_to_num(X)) + cams[placed, None, 3:]
        bad = ((Xc[..., 2] <= 0) & valid[placed]).any(0)
        X[bad] = np.nan
        return X

    partial = replace(settings.bundle, max_nfev=settings.partial_nfev)
    X = tri()
    cams, X, r = _bundle(cams, X, K, dist, xy, valid, weight, placed, fixed, partial)
    while not placed.all():
        have = np.isfinite(X).all(1)
        counts = (valid & have[None]).sum(1) * ~placed
        c = int(np.argmax(counts))
        if counts[c] < 6:
            raise CalibrationInputError(names[c], f"sees only {counts[c]} of the reconstructed keypoints: "
                                                  "not enough overlap with the other cameras")
        m = valid[c] & have
        ok, rvec, tvec, inl = cv2.solvePnPRansac(X[m], nxy[c, m], np.eye(3), None,
                                                 reprojectionError=settings.ransac_px / focal[c],
                                                 iterationsCount=1000, flags=cv2.SOLVEPNP_EPNP)
        if not ok:
            raise CalibrationInputError(names[c], "could not be placed against the other cameras' "
                                                  "reconstruction (PnP failed): check its keypoints")
        cams[c] = np.concatenate([rvec.reshape(3), tvec.reshape(3)])
        placed[c] = True
        order.append(c)
        X = tri()
        cams, X, r = _bundle(cams, X, K, dist, xy, valid, weight, placed, fixed, partial)
    use = valid.copy()
    for _ in range(2):
        err = np.linalg.norm(r, axis=-1)
        use &= ~(err > settings.outlier_px)
        X = np.where((use.sum(0) >= 2)[:, None], X, np.nan)
        cams, X, r = _bundle(cams, X, K, dist, xy, use, weight, placed, fixed, settings.bundle)
    return PeopleResult(cams, X, use & np.isfinite(X).all(1)[None], r, pairs, order)
