"""The hybrid's second cue: 2D keypoint detections beside the silhouettes (``hybrid_kp``).

One frame's detections are arranged per landmark and view as the marker tracker arranges
them (:func:`~mocap.energy.markers.arrange_detections`, the landmark set of
:func:`~mocap.body.catalogue.make_landmark_set`), and enter the hybrid three times:

- the local optimiser: the landmarks' point-line correspondences to their detections' rays,
  robust and confidence-weighted (:func:`mocap.local.keypoints.keypoint_lines`), each
  weighted ``weight`` against one contour correspondence;
- the APF and its acceptance test: the marker likelihood (:class:`~mocap.energy.markers.MarkerEnergy`,
  divided by tau^2 so that it lies in [0, 1]) x ``energy`` beside E_S;
- the misalignment test: a limb chain holding a landmark whose median reprojection distance
  over the views that see candidates for it exceeds ``flag`` x the gate is misaligned.

The keypoint-to-landmark offsets are learned as the marker tracker learns them
(:mod:`mocap.trackers.markers.offsets`) when ``offsets.frames`` > 0; they are off by default
(and in ``hybrid_kp``): where the keypoints mark the joints themselves (the real-motion
benchmark) the offsets the data give are the tracked joints' own constant error (the body's
proportions), and learning them raised joint and surface error on every dev sequence
(docs/results/surface.md, "Keypoint offsets"). With ``weight`` = 0 the cue is off and the
hybrid is today's, bit for bit.
"""

from __future__ import annotations

import warnings

import numpy as np

from mocap.body.bone_lengths import length_model, shrink_to_bounds, skeleton_length_model
from mocap.body.catalogue import make_landmark_set, rest_point_basis, rigid_pairs
from mocap.body.landmarks import LandmarkSet
from mocap.body.model import BodyModel, ShapedBody
from mocap.cameras import Rig, fundamental_matrices, view_rigs
from mocap.energy.markers import (
    MarkerEnergy,
    MarkerLikelihood,
    MarkerObservation,
    arrange_detections,
    reprojection_errors,
)
from mocap.local.keypoints import keypoint_lines
from mocap.local.misalignment import limb_chains
from mocap.local.solver import PointLines
from mocap.trackers.markers.offsets import local_residuals, robust_offsets
from mocap.trackers.markers.settings import MarkerInit
from mocap.trackers.markers.startup import (
    fit_shape,
    pinhole_rig,
    shape_from_landmarks,
    triangulate_candidates,
)
from mocap.trackers.tracker_settings import KeypointSettings


def check_detections(seq, name: str) -> None:
    """The one-line error, before any work, when ``seq`` has no 2D detections for the cue."""
    det = getattr(seq, "detections", None)
    if det is None or not len(det):
        raise ValueError(f"{name} uses 2D keypoint detections (tracker.keypoints.weight > 0), but sequence "
                         f"{seq.name!r} has none: use data with detections (e.g. data=real_bow_tall_man) "
                         "or tracker.keypoints.weight=0 (tracker=hybrid)")


def shape_from_frames(body: BodyModel, landmarks: LandmarkSet, measured: np.ndarray, init: MarkerInit,
                      prior_mean: np.ndarray, prior_std: float) -> tuple[np.ndarray, str | None]:
    """The shape alpha (K,) fitted to the median over frames of the distances that no pose
    changes between landmarks triangulated in several frames, ``measured`` (N, L, 3) world metres
    (NaN: unmeasured), as :func:`~mocap.trackers.markers.startup.shape_from_landmarks` fits one
    frame's (the same outlier test per frame, prior and bounds; ``init``: the marker tracker's
    start-up settings). One frame's triangulation is off by the detections' noise (a bone 5-20 mm
    on the real-motion benchmark), and a shape fitted to it keeps that error for the whole
    sequence; the median of N frames' lengths is ~sqrt(N) times closer. Second value: the
    bound flag, as there."""
    rest0, basis = rest_point_basis(body, landmarks)
    pairs = rigid_pairs(body, landmarks)
    pair_model = length_model(rest0, basis, pairs)
    lengths = pair_model.lengths(np.asarray(measured, np.float64))                 # (N, B)
    lengths[np.abs(pair_model.z_scores(lengths)) > init.outlier_sigma] = np.nan
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)              # a pair measured in no frame: NaN
        median = np.nanmedian(lengths, axis=0)
    alpha = fit_shape(rest0, basis, pairs, median, init.length_sigma, prior_mean=prior_mean,
                      prior_std=prior_std)
    bones, bone_names = skeleton_length_model(body)
    _, joints = body.rest(alpha[None])
    z = bones.z_scores(bones.lengths(np.asarray(joints[0], np.float64)))
    if np.abs(z).max() <= init.bound_sigma:
        return alpha, None
    worst = int(np.argmax(np.abs(z)))
    alpha, scale = shrink_to_bounds(body, alpha, bones, init.bound_sigma)
    return alpha, (f"fitted shape beyond the model's bounds ({bone_names[worst]} at {z[worst]:+.1f} "
                   f"sigma), shrunk towards the mean by {scale:.2f} to +-{init.bound_sigma:g} sigma")


class KeypointCue:
    """The cue's state for one tracker: the landmark set (made from the first frame's labels),
    the cameras without distortion, the learned offsets."""

    def __init__(self, body: BodyModel, rig: Rig, settings: KeypointSettings):
        self.body, self.rig, self.settings = body, rig, settings
        self.pinhole = pinhole_rig(rig)
        self._views = view_rigs(rig)
        self.F = fundamental_matrices(self.pinhole)
        diagonal = float(np.hypot(*np.asarray(rig.sizes, np.float64).mean(axis=0)))
        self.gate_px = settings.gate * diagonal
        self.likelihood = MarkerLikelihood(gate_px=self.gate_px, coherence_weight=0.0,
                                           use_confidence=settings.use_confidence)
        self.landmarks: LandmarkSet | None = None
        self.offsets: np.ndarray | None = None
        self._samples: list[np.ndarray] = []
        self.shape_samples: list[np.ndarray] = []      # (L, 3) landmarks triangulated per frame
        self._chain_of = np.full(body.num_joints, -1)               # joint -> limb chain index
        self.chains = limb_chains(body)
        for i, (_, limbs) in enumerate(self.chains):
            self._chain_of[limbs] = i

    def observe(self, frame) -> MarkerObservation | None:
        """The frame's detections arranged per landmark and view (None: the frame has none)."""
        det = frame.detections
        if det is None or not len(det):
            return None
        if self.landmarks is None:
            self.landmarks = make_landmark_set(self.body, self.settings.landmarks, det.labels)
        return arrange_detections(det, self.landmarks.names, self.rig, self.settings.min_confidence,
                                  views=self._views)

    def fitted_shape(self, obs: MarkerObservation, alpha: np.ndarray) -> tuple[np.ndarray, dict]:
        """The shape (K,) fitted to the rigid distances between the keypoints of ``obs``
        triangulated robustly (:func:`~mocap.trackers.markers.startup.shape_from_landmarks`,
        the marker tracker's start-up settings), its prior centred on ``alpha`` with standard
        deviation ``shape_std``; and a report (landmarks triangulated, the shift in the
        standardised coefficients, a flag when shrunk to the model's bounds)."""
        init = MarkerInit()
        measured, _ = triangulate_candidates(self.pinhole, obs, self.gate_px)
        fitted, flag = shape_from_landmarks(self.body, self.landmarks, measured, init.length_sigma,
                                            init.outlier_sigma, init.bound_sigma, prior_mean=alpha,
                                            prior_std=self.settings.shape_std)
        report = {"triangulated": int(np.isfinite(measured).all(axis=1).sum()),
                  "alpha_change": float(np.linalg.norm(fitted - np.asarray(alpha, np.float64)))}
        if flag is not None:
            report["flag"] = flag
        return fitted, report

    def triangulated(self, obs: MarkerObservation) -> np.ndarray:
        """(L, 3) this frame's landmarks triangulated robustly, world metres (NaN: too few views)."""
        return triangulate_candidates(self.pinhole, obs, self.gate_px)[0]

    def add_shape_sample(self, obs: MarkerObservation) -> int:
        """Triangulate this frame's keypoints for :meth:`shape_over_frames`; the samples so far."""
        self.shape_samples.append(self.triangulated(obs))
        return len(self.shape_samples)

    def shape_over_frames(self, prior_mean: np.ndarray) -> tuple[np.ndarray, dict]:
        """The shape (K,) fitted to the median bone lengths of the frames sampled so far
        (:func:`shape_from_frames`, prior N(``prior_mean``, ``shape_std``^2)) and a report."""
        fitted, flag = shape_from_frames(self.body, self.landmarks, np.stack(self.shape_samples),
                                         MarkerInit(), prior_mean, self.settings.shape_std)
        report = {"frames": len(self.shape_samples),
                  "alpha_change": float(np.linalg.norm(fitted - np.asarray(prior_mean, np.float64)))}
        if flag is not None:
            report["flag"] = flag
        return fitted, report

    def rest(self, shaped: ShapedBody) -> np.ndarray:
        """Rest landmarks (L, 3) of the shaped body, with the learned offsets."""
        rest = np.asarray(self.landmarks.rest_points(shaped), np.float64)
        return rest if self.offsets is None else rest + self.offsets

    def points(self, shaped: ShapedBody, chi: np.ndarray) -> np.ndarray:
        """Posed landmarks (L, 3) of one pose chi (D,)."""
        G = shaped.pose(np.asarray(chi, np.float64)[None]).transforms.astype(np.float64)
        return self.landmarks.from_transforms(G, self.rest(shaped))[0]

    def lines(self, shaped: ShapedBody, chi: np.ndarray, obs: MarkerObservation) -> PointLines:
        """The local optimiser's keypoint correspondences at pose chi (D,)."""
        s = self.settings
        return keypoint_lines(self.points(shaped, chi), self.landmarks.joint, obs, self.pinhole,
                              self.gate_px, s.weight, s.use_confidence)

    def energy(self, shaped: ShapedBody, obs: MarkerObservation) -> MarkerEnergy:
        """The marker likelihood of this frame (pixels^2; :meth:`scaled` brings it to [0, 1])."""
        return MarkerEnergy(self.landmarks, shaped, self.pinhole, obs, self.likelihood, F=self.F,
                            rest_offsets=self.offsets)

    def scaled(self, energy: MarkerEnergy, chi: np.ndarray) -> np.ndarray:
        """(P, D) -> (P,) ``energy`` x the marker likelihood / tau^2."""
        return self.settings.energy * energy(np.atleast_2d(chi)) / self.gate_px**2

    def misaligned(self, shaped: ShapedBody, chi: np.ndarray, obs: MarkerObservation) -> np.ndarray:
        """(J,) bool: the limbs of every chain holding a landmark whose median reprojection
        distance (capped at the gate) over the views with candidates exceeds ``flag`` x gate."""
        flagged = np.zeros(self.body.num_joints, bool)
        if not self.settings.flag:
            return flagged
        err = reprojection_errors(self.points(shaped, chi), obs, self.pinhole, self.gate_px)   # (L, C)
        seen = obs.valid.any(axis=2)
        err = np.where(seen, np.nan_to_num(err, nan=self.gate_px), np.nan)
        with np.errstate(all="ignore"):
            med = np.nanmedian(np.where(seen.sum(axis=1, keepdims=True) >= 2, err, np.nan), axis=1)
        bad = np.nan_to_num(med, nan=0.0) > self.settings.flag * self.gate_px
        for c in np.unique(self._chain_of[self.landmarks.joint[bad]]):
            if c >= 0:
                flagged[self.chains[c][1]] = True
        return flagged

    def learn_offsets(self, shaped: ShapedBody, chi: np.ndarray, obs: MarkerObservation) -> None:
        """One frame's residuals for the offsets (:mod:`mocap.trackers.markers.offsets`);
        the offsets are set once ``offsets.frames`` frames are in."""
        s = self.settings.offsets
        if not s.frames or self.offsets is not None:
            return
        X, _ = triangulate_candidates(self.pinhole, obs, self.gate_px)
        G = shaped.pose(np.asarray(chi, np.float64)[None]).transforms[0].astype(np.float64)
        rest = np.asarray(self.landmarks.rest_points(shaped), np.float64)
        self._samples.append(local_residuals(G[self.landmarks.joint], X, rest))
        if len(self._samples) >= s.frames:
            self.offsets = robust_offsets(np.stack(self._samples), s)
