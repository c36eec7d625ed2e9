"""The two-cue hybrid's shape fitted once over many tracked frames to both cues at once
(``tracker.keypoints.two_cue``, :class:`~mocap.trackers.tracker_settings.TwoCueShape`).

The silhouettes measure the body's outline, the keypoints its bone lengths; our PCA body cannot
take both of a foreign body's exactly (docs/results/surface.md, "Shape or pose"), and the chain
it replaces (a frame-0 silhouette shape, keypoint fits under an isotropic prior around it,
silhouette-only refinements after) only slides along that trade-off. Here one negative
log-likelihood over N tracked frames, poses held as tracked, is minimised over the first C shape
coefficients and a shared shift of the body:

    E(alpha, s) = sum_b n_b (L_b(alpha) - m_b)^2 / (2 sigma_b^2)           (keypoints)
                + w sum_f sum_v E_S,fv(alpha, s) / E_S,fv(alpha_0, 0)       (silhouettes)
                + p |alpha_1..C|^2 / 2                                       (the model's prior, p: ``prior``)

- ``m_b``, ``sigma_b``, ``n_b``: the median, robust spread (1.4826 MAD, at least
  ``length_floor``) and count over the frames of the distance between two landmarks that no pose
  changes, triangulated from each frame's keypoints: every frame is one measurement of every
  bone length with that noise, so n_b / sigma_b^2 is the bone's evidence;
- ``E_S,fv``: the silhouette energy (a mean distance, px) of view v of keyframe f, divided by its
  value at the current shape (its residual scale: a Laplace likelihood's scale), each view
  counted as ``view_samples`` = w independent samples;
- the search: in the coordinates of the keypoints' posterior (each unit one standard deviation
  the bone lengths and the prior leave, :meth:`LengthEvidence.posterior_root`), the annealed
  particle filter (:func:`~mocap.trackers.apf.run_apf`) from the best of the current shape, the
  keypoints' own fit and the point halfway, then Powell's line searches (scipy) from its result,
  then (``quadratic`` > 0) that many iterations of a trust region on a quadratic model of batched
  samples (:mod:`mocap.trackers.quadratic_polish`), which goes on where Powell stalls in the
  silhouettes' pixel noise.

Each term's minimum is a different shape; their sum puts the shape where the directions each
cue measures are met by that cue (the keypoints' bone lengths, the silhouettes' girth) rather
than along one line between two fits.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from mocap.body.bone_lengths import length_model, shrink_to_bounds, skeleton_length_model
from mocap.body.catalogue import rest_point_basis, rigid_pairs
from mocap.body.landmarks import LandmarkSet
from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy.silhouette import silhouette_target
from mocap.trackers.apf import run_apf
from mocap.trackers.quadratic_polish import quadratic_polish
from mocap.trackers.shape_search import shape_energy
from mocap.trackers.tracker_settings import APFSettings, TwoCueShape

#: measured lengths this many shape-model sigmas from the model's mean are outliers (the marker
#: tracker's start-up value, :class:`~mocap.trackers.markers.settings.MarkerInit`)
OUTLIER_SIGMA = 8.0
#: a fitted bone beyond the model's mean +- this many sigmas shrinks the shape (as there)
BOUND_SIGMA = 6.0


@dataclass(frozen=True)
class LengthEvidence:
    """The keypoints' bone lengths over frames: rest points R(alpha) = rest0 (L, 3) + sum_k
    alpha_k basis_k (basis (K, L, 3)), landmark ``pairs`` (B, 2) that no pose changes, and per
    pair the ``median`` (B,) m, per-frame ``spread`` (B,) sigma and ``count`` (B,) n of the
    measured lengths (pairs measured in fewer than 2 frames have n = 0)."""

    rest0: np.ndarray
    basis: np.ndarray
    pairs: np.ndarray
    median: np.ndarray
    spread: np.ndarray
    count: np.ndarray

    def lengths(self, alphas: np.ndarray) -> np.ndarray:
        """(P, K) -> (P, B): the pairs' lengths of the shapes (m)."""
        R = self.rest0 + np.einsum("pk,klc->plc", np.atleast_2d(alphas), self.basis)
        return np.linalg.norm(R[:, self.pairs[:, 0]] - R[:, self.pairs[:, 1]], axis=-1)

    @property
    def weight(self) -> np.ndarray:
        """(B,) n_b / sigma_b^2: each pair's evidence (1/m^2)."""
        return self.count / self.spread**2

    def energy(self, alphas: np.ndarray) -> np.ndarray:
        """(P, K) -> (P,): sum_b n_b (L_b - m_b)^2 / (2 sigma_b^2)."""
        d = np.nan_to_num(self.lengths(alphas) - self.median)
        return 0.5 * (self.weight * d**2).sum(axis=1)

    def jacobian(self, alpha: np.ndarray, components: int) -> np.ndarray:
        """(B, C): d L_b / d alpha_k at ``alpha`` (K,), each row x sqrt(n_b) / sigma_b."""
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        R = self.rest0 + np.einsum("k,klc->lc", np.asarray(alpha, np.float64), self.basis)
        v = R[i] - R[j]
        u = v / np.linalg.norm(v, axis=1)[:, None]
        J = np.einsum("bc,kbc->bk", u, self.basis[:components, i] - self.basis[:components, j])
        return J * np.sqrt(self.weight)[:, None]

    def posterior_root(self, alpha: np.ndarray, components: int, prior: float = 1.0) -> np.ndarray:
        """(C, C) the symmetric square root of (J^T J + p I)^-1 at ``alpha`` (p: the model
        prior's weight ``prior``): the spread of the first C coefficients that the bone lengths
        and the prior leave (Laplace), the search's coordinates (one unit: one standard
        deviation along each direction). Directions neither constrains (p = 0) are given the
        spread of a prior of weight 1e-6."""
        J = self.jacobian(alpha, components)
        lam, V = np.linalg.eigh(J.T @ J + max(prior, 1e-6) * np.eye(components))
        return (V / np.sqrt(lam)) @ V.T

    def fit(self, alpha: np.ndarray, components: int, iterations: int = 20, prior: float = 1.0) -> np.ndarray:
        """The shape (K,) minimising :meth:`energy` + p |alpha_1..C|^2 / 2 (p: ``prior``, the
        model prior's weight; 0: least squares) over the first ``components`` coefficients of
        ``alpha`` (the rest held): Gauss-Newton (Levenberg's damping 1e-9 where p = 0)."""
        alpha = np.array(alpha, np.float64)
        C = min(components, len(alpha))
        w = np.sqrt(self.weight)
        p = float(prior)
        for _ in range(iterations):
            r = w * np.nan_to_num(self.lengths(alpha)[0] - self.median)
            J = self.jacobian(alpha, C)
            step = np.linalg.solve(J.T @ J + max(p, 1e-9) * np.eye(C), -(J.T @ r + p * alpha[:C]))
            alpha[:C] += step
            if np.abs(step).max() < 1e-7:
                break
        return alpha


def length_evidence(body: BodyModel, landmarks: LandmarkSet, measured: np.ndarray,
                    floor: float) -> LengthEvidence:
    """The evidence of landmarks ``measured`` (N, L, 3) world metres in N frames (NaN:
    unmeasured): :class:`LengthEvidence` over the landmark pairs no pose changes
    (:func:`~mocap.body.catalogue.rigid_pairs`), lengths beyond ``OUTLIER_SIGMA`` model sigmas
    dropped, the spread at least ``floor`` (m)."""
    measured = np.asarray(measured, np.float64)
    if measured.ndim != 3 or measured.shape[1:] != (len(landmarks), 3):
        raise ValueError(f"two-cue shape: measured landmarks have shape {measured.shape}, expected "
                         f"(frames, {len(landmarks)}, 3)")
    rest0, basis = rest_point_basis(body, landmarks)
    pairs = rigid_pairs(body, landmarks)
    model = length_model(rest0, basis, pairs)
    lengths = model.lengths(measured)                                            # (N, B)
    lengths[np.abs(model.z_scores(lengths)) > OUTLIER_SIGMA] = np.nan
    count = np.isfinite(lengths).sum(axis=0)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)            # a pair measured in no frame: NaN
        median = np.nanmedian(lengths, axis=0)
        mad = 1.4826 * np.nanmedian(np.abs(lengths - median), axis=0)
    count = np.where(count >= 2, count, 0)
    return LengthEvidence(rest0, basis, pairs, np.where(count > 0, median, np.nan),
                          np.maximum(np.nan_to_num(mad, nan=floor), floor), count.astype(np.float64))


def silhouette_evidence(body: BodyModel, rig: Rig, alpha: np.ndarray, chis: np.ndarray, masks,
                        components: int, resolution: int, compiled: bool = True):
    """The silhouette term: a function (P, components + 3) -> (P,), sum over the keyframes
    (poses chis (N, D) held, masks N of (C, H, W) bool) and their valid views of E_S with the
    first ``components`` coefficients and a shared world shift (the last 3, m) over E_S of
    ``alpha`` (K,) unshifted, at ``resolution`` px; and the number of frame-views summed."""
    chis = np.atleast_2d(np.asarray(chis, np.float64))
    scale = rig.scale_for(resolution)
    small = rig.scaled(scale)
    targets = [silhouette_target(m, scale, view_names=tuple(rig.names)) for m in masks]
    if len(targets) != len(chis):
        raise ValueError(f"two-cue shape: {len(chis)} poses for {len(targets)} silhouette masks")
    base = np.asarray(alpha, np.float64)
    C = min(components, len(base))
    per_view = shape_energy(body, small, chis, targets, C, translate=True, alpha=base, compiled=compiled,
                            per_view=True)

    scale0 = per_view(np.r_[base[:C], np.zeros(3)])

    def energy(x: np.ndarray) -> np.ndarray:
        total = np.zeros(len(np.atleast_2d(x)))
        for e, e0 in zip(per_view(x), scale0, strict=True):
            total += np.nansum(e / np.maximum(e0, 1e-9), axis=1)
        return total

    return energy, int(sum(np.isfinite(e0).sum() for e0 in scale0))


@dataclass(frozen=True)
class TwoCueFit:
    """One fit: the shape (K,) and shift (3,) found and a report (terms before and after)."""

    alpha: np.ndarray
    shift: np.ndarray
    report: dict


def fit_two_cue_shape(body: BodyModel, rig: Rig, landmarks: LandmarkSet, alpha: np.ndarray,
                      measured: np.ndarray, chis: np.ndarray, masks, settings: TwoCueShape,
                      rng: np.random.Generator) -> TwoCueFit:
    """The shape of the module docstring from the current ``alpha`` (K,): the landmarks
    ``measured`` (M, L, 3) in M frames, the keyframes' poses ``chis`` (N, D) and masks (N of
    (C, H, W) bool; N may be 0: the keypoints alone)."""
    alpha = np.asarray(alpha, np.float64)
    C = min(settings.components, body.num_shape)
    lengths = length_evidence(body, landmarks, measured, settings.length_floor)
    w = float(settings.view_samples)
    if len(chis) and w > 0:
        sil, views = silhouette_evidence(body, rig, alpha, chis, masks, C, settings.resolution)
    else:
        sil, views, w = (lambda x: np.zeros(len(np.atleast_2d(x)))), 0, 0.0

    def full(x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(x)
        a = np.repeat(alpha[None], len(x), axis=0)
        a[:, :C] = x[:, :C]
        return a

    def terms(x: np.ndarray) -> dict[str, np.ndarray]:
        x = np.atleast_2d(x)
        return {"keypoints": lengths.energy(full(x)), "silhouettes": w * sil(x),
                "prior": 0.5 * settings.prior * (x[:, :C] ** 2).sum(axis=1)}

    def energy(x: np.ndarray) -> np.ndarray:
        return sum(terms(x).values())

    keypoints_only = lengths.fit(alpha, C, prior=settings.prior)
    root = lengths.posterior_root(keypoints_only, C, settings.prior)             # (C, C)

    def shape_of(z: np.ndarray) -> np.ndarray:
        """(P, C + 3) search coordinates -> (P, C + 3) coefficients and shift."""
        z = np.atleast_2d(z)
        return np.hstack([keypoints_only[:C] + z[:, :C] @ root.T, z[:, C:]])

    def searched(z: np.ndarray) -> np.ndarray:
        return energy(shape_of(z))

    zero = np.zeros(3)
    current = np.r_[np.linalg.solve(root, alpha[:C] - keypoints_only[:C]), zero]
    starts = np.stack([np.zeros(C + 3), 0.5 * current, current])
    z0 = starts[int(np.argmin(searched(starts)))]
    std = np.r_[np.full(C, settings.std), np.full(3, max(settings.shift, 1e-6) / 2)]
    reach = max(4.0, 1.5 * float(np.abs(current[:C]).max()))
    limits = np.vstack([np.tile([-reach, reach], (C, 1)), np.tile([-settings.shift, settings.shift], (3, 1))])
    apf = APFSettings(particles=settings.particles, layers=settings.layers, diffusion=0.7, shrink=0.85)
    z, _ = run_apf(searched, np.clip(z0, limits[:, 0], limits[:, 1]), std, limits, apf, rng)
    if searched(z)[0] > searched(z0)[0]:
        z = z0
    if settings.polish:
        found = minimize(lambda v: float(searched(v)[0]), z, method="Powell",
                         bounds=list(map(tuple, limits)),
                         options={"maxfev": settings.polish, "xtol": 1e-2, "ftol": 1e-4})
        if found.fun < searched(z)[0]:
            z = found.x
    polished = None
    if settings.quadratic:
        scale = np.r_[np.ones(C), np.full(3, max(settings.shift, 1e-6) / 2)]     # the shift in its spreads
        v, _, polished = quadratic_polish(lambda u: searched(u * scale), z / scale, settings.quadratic_radius,
                                          settings.quadratic, rng, lower=limits[:, 0] / scale,
                                          upper=limits[:, 1] / scale)
        z = v * scale
    x = shape_of(z)[0]
    x0 = np.r_[alpha[:C], zero]
    new = full(x)[0]
    bones, _ = skeleton_length_model(body)
    _, joints = body.rest(new[None])
    flag = None
    if np.abs(bones.z_scores(bones.lengths(np.asarray(joints[0], np.float64)))).max() > BOUND_SIGMA:
        new, s = shrink_to_bounds(body, new, bones, BOUND_SIGMA)
        flag = f"shrunk towards the mean by {s:.2f} to the model's bounds"
    before, after = terms(x0), terms(x)
    report = {"frames": int(len(measured)), "keyframes": int(len(chis)), "views": views,
              "bones": int((lengths.count > 0).sum()),
              "alpha_change": float(np.linalg.norm(new - alpha)),
              "keypoints_only_change": float(np.linalg.norm(keypoints_only - alpha)),
              "before": {k: float(v[0]) for k, v in before.items()},
              "after": {k: float(v[0]) for k, v in after.items()}}
    if polished is not None:
        report["quadratic"] = polished
    if flag:
        report["flag"] = flag
    return TwoCueFit(new, x[C:C + 3].copy(), report)


class TwoCueState:
    """The frames a tracker keeps for :func:`fit_two_cue_shape`: every frame's triangulated
    landmarks (L, 3) and the poses and masks of the frames whose check flagged nothing (with
    ``aligned_only`` off: of every frame, the repaired pose of a flagged one)."""

    def __init__(self, settings: TwoCueShape):
        self.settings = settings
        self.measured: list[np.ndarray] = []
        self.keyframes: list[tuple[int, np.ndarray, np.ndarray]] = []      # (index, chi, masks)
        self.measured_at: dict[int, np.ndarray] = {}                       # index -> (L, 3)
        self.observed: dict[int, tuple] = {}      # keyframe index -> (frame, its keypoints): skeleton_refit's
        self.fits = 0
        self.reports: list[dict] = []

    @property
    def fits_to_come(self) -> bool:
        """Whether a fit may still come (none yet, or one every ``every`` frames)."""
        return not self.fits or bool(self.settings.every)

    def add(self, index: int, chi: np.ndarray, masks: np.ndarray | None, measured: np.ndarray,
            aligned: bool, observed: tuple | None = None) -> None:
        """One tracked frame: its pose, masks, triangulated landmarks and whether its check
        flagged nothing; ``observed`` (the frame, its keypoints): kept with a keyframe for
        ``skeleton_refit`` while a fit may still come (not for the rest of a run whose fits are
        done: a frame holds its images)."""
        self.measured.append(np.asarray(measured, np.float64))
        self.measured_at[int(index)] = self.measured[-1]
        if (aligned or not self.settings.aligned_only) and masks is not None:
            self.keyframes.append((int(index), np.asarray(chi, np.float64), masks))
            if self.settings.skeleton_refit and observed is not None and self.fits_to_come:
                self.observed[int(index)] = observed

    def due(self) -> bool:
        """Whether a fit is due now: ``frames`` frames in for the first, then every ``every``."""
        s, n = self.settings, len(self.measured)
        if not self.fits:
            return n >= s.frames
        return bool(s.every) and n >= s.frames + self.fits * s.every

    def chosen(self) -> list[tuple[int, np.ndarray, np.ndarray]]:
        """At most ``keyframes`` of the aligned frames, evenly spaced (the first and last kept)."""
        k, n = self.settings.keyframes, len(self.keyframes)
        if n <= k:
            return list(self.keyframes)
        return [self.keyframes[i] for i in np.unique(np.round(np.linspace(0, n - 1, k)).astype(int))]

    def skeleton_frames(self) -> tuple[list[int], np.ndarray, np.ndarray]:
        """The aligned frames' indices, poses (N, D) and triangulated landmarks (N, L, 3) (every
        kept keyframe, not only the :meth:`chosen` ones): the skeleton fit's evidence."""
        if not self.keyframes:
            return [], np.zeros((0, 0)), np.zeros((0, 0, 3))
        return ([f for f, _, _ in self.keyframes], np.stack([c for _, c, _ in self.keyframes]),
                np.stack([self.measured_at[f] for f, _, _ in self.keyframes]))

    def shifted(self, move) -> None:
        """The kept poses moved by the shift that came with a fit."""
        self.keyframes = [(f, move(c), m) for f, c, m in self.keyframes]
