"""``marker_apf``: the marker-based tracker of Canton-Ferrer, Casas & Pardàs 2010.

An annealed particle filter over the body's pose, fed by 2D marker (or keypoint)
detections in calibrated views: the likelihood of :mod:`mocap.energy.markers` (outlier
gating, generalised symmetric epipolar distance, occlusion management with temporal
coherence), survival-rate annealing, propagation by a Gaussian truncated to the joint
limits (:mod:`mocap.trackers.markers.propagation`), and initialisation from triangulated
detections with the body's size fitted to the subject (:mod:`mocap.trackers.markers.startup`).

The landmark set is configurable: ``"auto"`` fits every detection label the catalogue
knows (:mod:`mocap.body.catalogue`), so the same tracker runs on synthetic
markers and on OpenPose keypoints.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from mocap.body.catalogue import dof_moves, make_landmark_set
from mocap.body.kinematics import chain_transforms
from mocap.body.landmarks import LandmarkSet
from mocap.body.model import BodyModel, ShapedBody
from mocap.body.root_motion import predict_root
from mocap.cameras import Rig, fundamental_matrices, view_rigs
from mocap.data.openpose import capture_centre
from mocap.energy.markers import (
    MarkerEnergy,
    MarkerObservation,
    arrange_detections,
    reprojection_errors,
    views_near,
)
from mocap.trackers.annealed_step import AnnealedStep
from mocap.trackers.base import Frame
from mocap.trackers.contract import Needs, OnePerson, SearchBudget, Uncached
from mocap.trackers.diagnostics import LandmarkReport, RefineTrace, StepDiagnostics
from mocap.trackers.markers.associate import associate_people, person_detections, skeletons_of
from mocap.trackers.markers.crossover import PartGroup, part_groups, run_annealing
from mocap.trackers.markers.offsets import (
    local_residuals,
    profile_rest_offsets,
    remove_profile,
    robust_offsets,
)
from mocap.trackers.markers.refine import refine_pose
from mocap.trackers.markers.settings import MarkerInit, MarkerSettings  # noqa: F401  (MarkerInit: re-exported)
from mocap.trackers.markers.startup import (
    neutral_pose,
    pinhole_rig,
    root_rigid,
    shape_from_landmarks,
    triangulate_candidates,
)
from mocap.trackers.silhouette_tracker import diffusion_std
from mocap.trackers.tracker_settings import APFSettings


class MarkerAPFTracker(AnnealedStep, OnePerson):
    """Tracks one subject from 2D detections (see the module docstring)."""

    needs = Needs(detections=True)

    def __init__(self, body: BodyModel, rig: Rig, settings: MarkerSettings, rng: np.random.Generator,
                 name: str = "marker_apf"):
        self.body, self.rig, self.tracker_settings = body, rig, settings
        self.settings = settings.search
        self.likelihood = settings.likelihood(rig.sizes)
        self.rng, self.name, self.keep_particles = rng, name, settings.keep_particles
        self.landmark_spec = settings.landmark_spec()
        self.std0 = diffusion_std(body, *settings.init_std)
        self.damping = settings.prediction_damping
        self.min_confidence = settings.min_confidence
        self.init = settings.init
        self.crossover = settings.crossover
        self.groups: list[PartGroup] = []
        self.pinhole = pinhole_rig(rig)
        self._views = view_rigs(rig)                  # one-camera rigs, for arrange_detections
        self.F = fundamental_matrices(self.pinhole)
        self.landmarks: LandmarkSet | None = None
        self.shaped: ShapedBody | None = None
        self._rest: tuple[ShapedBody, np.ndarray] | None = None     # rest landmarks of self.shaped
        self.history: list[np.ndarray] = []
        self.start_up_flags: list[str] = []
        self.start_up: dict = {}
        self.refinement = settings.refine
        self.offset_learning = settings.offsets
        self.offsets: np.ndarray | None = None          # (L, 3): the profile's, then learned
        self.profile = None if settings.keypoint_profile == "auto" else settings.keypoint_profile
        self._auto_profile = settings.keypoint_profile == "auto"
        self._offsets_learned = False
        self._offset_samples: list[np.ndarray] = []
        self._refined: RefineTrace | None = None

    # -- set-up ------------------------------------------------------------------------
    @property
    def budget(self) -> SearchBudget:
        return SearchBudget(self.settings.particles, self.settings.layers)

    def initializer(self, cache=None):
        """:meth:`initial_estimate` as a start (never cached: its key would need the detections)."""
        from mocap.trackers.init_cache import Cached

        return Cached(MarkerStart(self), cache)

    def check_sequence(self, seq) -> None:
        """Raise a ValueError, before any work starts, when ``seq`` cannot be tracked: no
        detections at all, none in the first frame, or no detection label the landmark set
        knows (``mocap track`` calls this right after building the tracker)."""
        det = seq.detections
        if det is None or not len(det):
            raise ValueError(f"{self.name} needs 2D detections, but sequence {seq.name!r} has none: use "
                             "data with detections (e.g. data=walk_markers_small, "
                             "or a keypoint recording such as data=pose2sim_demo), or a silhouette tracker")
        make_landmark_set(self.body, self.landmark_spec, det.labels)          # raises on unknown names
        if self._auto_profile:          # the detector profile the detections declare (or none)
            self.profile = (seq.meta.get("detections") or {}).get("keypoint_profile")
        if not np.any(det.frame == 0):
            raise ValueError(f"{self.name}: sequence {seq.name!r} has no detections in its first frame")

    def _landmarks_for(self, frame: Frame) -> LandmarkSet:
        if frame.detections is None:
            raise ValueError(f"{self.name}: frame {frame.index} has no detections; the marker "
                             "tracker needs 2D detections (data with detections enabled, e.g. "
                             "data=walk_markers_small, or a keypoint recording such as data=pose2sim_demo)")
        if self.landmarks is None:
            self.landmarks = make_landmark_set(self.body, self.landmark_spec, frame.detections.labels)
            if self.profile is not None:
                profile_rest_offsets(self.profile, self.landmarks.names,       # raises: names it needs
                                     np.zeros((len(self.landmarks), 3)))
            if self.crossover:
                self.groups = part_groups(dof_moves(self.body, self.landmarks))
        return self.landmarks

    def observe(self, frame: Frame) -> MarkerObservation:
        lms = self._landmarks_for(frame)
        return arrange_detections(frame.detections, lms.names, self.rig, self.min_confidence,
                                  views=self._views)

    def initialize(self, chi: np.ndarray, alpha: np.ndarray) -> None:
        chi = np.asarray(chi, np.float64)
        if chi.shape != (self.body.num_dofs,) or not np.all(np.isfinite(chi)):
            raise ValueError(f"initial pose must be a finite ({self.body.num_dofs},) vector")
        self.shaped = self.body.shaped(alpha)
        self.history = [chi]
        self.offsets, self._offsets_learned, self._offset_samples = None, False, []

    def initial_estimate(self, frame: Frame) -> tuple[np.ndarray, np.ndarray]:
        """(chi (D,), alpha (K,)) from one frame of labelled detections (Sec. 3.1), robust to
        other people in view and to implausible fits:

        1. Sources of 3D landmarks: when the detections group keypoints into skeletons
           (``Detections.person``), the people associated across views by whole-skeleton
           epipolar consistency (:mod:`mocap.trackers.markers.associate`), the subject being
           the one seen in the most views (then nearest the capture centre), triangulated
           from that person's detections only; and always the per-landmark RANSAC
           triangulation of every candidate (:func:`triangulate_candidates`).
        2. Per source, the shape fitted to the rigid landmark distances, pairs more than
           ``init.outlier_sigma`` standard deviations of the shape model from their mean
           ignored (:mod:`mocap.body.bone_lengths`); a fitted body with a bone outside
           the model's +-``init.bound_sigma`` sigma is shrunk towards the mean shape until
           every bone is inside (flagged in ``start_up_flags``). The mean shape is a
           hypothesis too.
        3. Each hypothesis (source x shape) is posed by annealed IK and scored by the marker
           likelihood of the frame (all candidates); the lowest energy wins.
        """
        obs = self.observe(frame)
        lms = self.landmarks
        self.start_up_flags: list[str] = []
        sources = self._start_up_sources(frame, obs)
        if self.profile is not None:        # the detector's keypoints -> the anatomical points
            sources = [(name, self._without_profile(X)) for name, X in sources]
        if not sources:
            raise ValueError(f"{self.name}: frame {frame.index}: fewer than 3 landmarks could be "
                             "triangulated (the initialisation needs labelled detections in >= 2 views)")
        tried: list[tuple[float, np.ndarray, np.ndarray, str]] = []
        for source, measured in sources:
            shapes = [("mean shape", np.zeros(self.body.num_shape))]
            if self.init.fit_shape:
                alpha, flag = shape_from_landmarks(self.body, lms, measured, self.init.length_sigma,
                                                   self.init.outlier_sigma, self.init.bound_sigma)
                if flag is not None:
                    self.start_up_flags.append(f"start-up ({source}): {flag}")
                shapes.insert(0, ("fitted shape", alpha))
            for shape_name, alpha in shapes:
                shaped = self.body.shaped(alpha)
                rest = lms.rest_points(shaped).astype(np.float64)
                chi = neutral_pose(self.body, rest, measured, root_rigid(self.body, lms))
                chi = self._fit_to_points(shaped, chi, measured)
                energy = MarkerEnergy(lms, shaped, self.pinhole, obs, self.likelihood, F=self.F,
                                      rest_offsets=self._profile_offsets(shaped))
                if self.init.refine_iterations:     # score each shape at its best pose, not the IK's
                    chi, _ = refine_pose(energy.points, chi, obs, self.pinhole, self.body.limits,
                                         replace(self.refinement, iterations=self.init.refine_iterations,
                                                 prior_std=1.0), self.likelihood.gate_px)
                tried.append((float(energy(chi[None])[0]), chi, alpha, f"{source}, {shape_name}"))
        e, chi, alpha, label = min(tried, key=lambda t: t[0])
        self.start_up = {"chosen": label, "energies": {t[3]: t[0] for t in tried},
                         "flags": list(self.start_up_flags)}
        if "mean shape" in label and self.init.fit_shape and not self.start_up_flags:
            self.start_up_flags.append(f"start-up: the mean shape fitted the detections better ({label})")
        return chi, alpha

    def _profile_offsets(self, shaped: ShapedBody) -> np.ndarray | None:
        """The detector profile's offsets (L, 3) in the rest frames of ``shaped`` (None: no profile)."""
        if self.profile is None:
            return None
        rest = self.landmarks.rest_points(shaped).astype(np.float64)
        return profile_rest_offsets(self.profile, self.landmarks.names, rest)

    def _without_profile(self, X: np.ndarray) -> np.ndarray:
        """Triangulated keypoints (L, 3) minus the profile's offsets; where the keypoint frames
        are unknown (torso keypoints unmeasured) the keypoints as measured."""
        Y = remove_profile(self.profile, self.landmarks.names, X)
        return np.where(np.isfinite(Y), Y, X)

    def _start_up_sources(self, frame: Frame, obs: MarkerObservation) -> list[tuple[str, np.ndarray]]:
        """[(name, measured landmarks (L, 3) world, NaN = unmeasured)] of the module's start-up."""
        gate = self.likelihood.gate_px
        out = []
        det = frame.detections
        sk = skeletons_of(det, self.landmarks.names, self.rig)
        if sk is not None and sum(len(x) > 0 for x in sk.xy) >= 2:
            people = associate_people(sk, self.F, self.init.association_px or gate)
            if people:
                centre = capture_centre(self.pinhole)
                best = None
                for person, _ in people:
                    sub = arrange_detections(person_detections(det, sk, person), self.landmarks.names,
                                             self.rig, self.min_confidence)
                    X, _ = triangulate_candidates(self.pinhole, sub, gate)
                    if np.isfinite(X[:, 0]).sum() < 3:
                        continue
                    views = sum(i is not None for i in person)
                    key = (views, -float(np.linalg.norm(np.nanmedian(X, axis=0) - centre)))
                    if best is None or key > best[0]:
                        best = (key, X)
                if best is not None:
                    out.append((f"associated person ({len(people)} in view)", best[1]))
        measured, _ = triangulate_candidates(self.pinhole, obs, gate)
        if np.isfinite(measured[:, 0]).sum() >= 3:
            out.append(("per-landmark triangulation", measured))
        return out

    def _fit_to_points(self, shaped: ShapedBody, chi: np.ndarray, target: np.ndarray) -> np.ndarray:
        """Annealed inverse kinematics: landmarks of chi towards target (L, 3), NaN ignored;
        a robust (truncated at 0.3 m) squared distance per landmark, with crossover."""
        have = np.all(np.isfinite(target), axis=1)
        tgt = np.where(have[:, None], target, 0.0)
        lms = self.landmarks

        def costs(x):
            d2 = ((lms.positions(shaped, x).astype(np.float64) - tgt) ** 2).sum(-1)
            return np.where(have, np.minimum(d2, 0.09), 0.0)

        s = self.init
        settings = APFSettings(particles=s.particles, layers=s.layers, survival=self.settings.survival,
                               diffusion=self.settings.diffusion, shrink=self.settings.shrink,
                               min_std_fraction=self.settings.min_std_fraction)
        for k in range(s.passes):
            std = diffusion_std(self.body, *s.std) * s.shrink**k
            chi, _ = run_annealing(costs, chi, std, self.body.limits, settings, self.rng,
                                   root_point=shaped.rest_joints[0], groups=self.groups)
        return chi

    # -- tracking ----------------------------------------------------------------------
    def predict(self) -> np.ndarray:
        """Constant velocity: angles chi_t + d (chi_t - chi_{t-1}), the root on SE(3)."""
        if len(self.history) < 2:
            return np.array(self.history[-1], np.float64)
        a, b = self.history[-2], self.history[-1]
        out = b + self.damping * (b - a)
        out[:6] = predict_root(a[:6], b[:6], self.damping)
        return np.clip(out, self.body.limits[:, 0], self.body.limits[:, 1])

    def rest_landmarks(self) -> np.ndarray:
        """The landmarks' rest points (L, 3) of the tracked shape (``landmarks.rest_points``,
        computed once per shape)."""
        if self._rest is None or self._rest[0] is not self.shaped:
            self._rest = (self.shaped, self.landmarks.rest_points(self.shaped))
        return self._rest[1]

    def landmark_positions(self, chi: np.ndarray) -> np.ndarray:
        """``landmarks.positions(shaped, chi)`` (P, L, 3) of poses chi (P, D), the rest points
        computed once per shape."""
        m = self.landmarks.model
        chi = np.atleast_2d(np.asarray(chi, dtype=m.dtype))
        G = chain_transforms(m.parents, m.dof_joint, self.shaped.axes, self.shaped.rest_joints,
                             chi[:, :6], chi[:, 6:])
        return self.landmarks.from_transforms(G, self.rest_landmarks())

    def frame_energy(self, frame: Frame, predicted: np.ndarray) -> tuple[MarkerEnergy, np.ndarray]:
        obs = self.observe(frame)
        lms = self.landmarks
        if self.offsets is None and self.profile is not None:
            self.offsets = self._profile_offsets(self.shaped)
        pred_pts = self.landmark_positions(predicted[None])[0].astype(np.float64)
        n_views = views_near(obs, self.pinhole, pred_pts, self.likelihood.gate_px)
        weak = n_views < self.likelihood.min_views
        energy = MarkerEnergy(lms, self.shaped, self.pinhole, obs, self.likelihood, F=self.F,
                              predicted=pred_pts, weak=weak, rest_offsets=self.offsets,
                              rest_points=self.rest_landmarks())
        return energy, n_views

    def _learn_offsets(self, energy: MarkerEnergy, chi: np.ndarray) -> None:
        """Collect one frame's keypoint residuals; set the offsets when enough are in."""
        s = self.offset_learning
        if not s.frames or self._offsets_learned:
            return
        X, _ = triangulate_candidates(self.pinhole, energy.obs, self.likelihood.gate_px)
        G = self.shaped.pose(chi[None]).transforms[0].astype(np.float64)[self.landmarks.joint]
        prior = np.zeros((len(self.landmarks), 3)) if self.offsets is None else self.offsets
        rest = self.landmarks.rest_points(self.shaped).astype(np.float64) + prior
        self._offset_samples.append(local_residuals(G, X, rest))
        if len(self._offset_samples) >= s.frames:          # the profile's, plus what this sequence adds
            self.offsets = prior + robust_offsets(np.stack(self._offset_samples), s)
            self._offsets_learned = True

    def search(self, energy: MarkerEnergy, predicted: np.ndarray):
        chi, trace = run_annealing(energy.landmark_costs, predicted, self.std0, self.body.limits,
                                   self.settings, self.rng, keep_particles=self.keep_particles,
                                   previous=self.history[-1], root_point=self.shaped.rest_joints[0],
                                   groups=self.groups)
        return self.after_annealing(energy, chi), trace

    def after_annealing(self, energy: MarkerEnergy, chi: np.ndarray) -> np.ndarray:
        """The annealed estimate chi (D,) refined (Gauss-Newton), offsets learned: the rest of
        :meth:`search` (the several-people tracker anneals its people together)."""
        info = None
        if self.refinement.iterations:          # Gauss-Newton on the reprojection error
            chi, info = refine_pose(energy.points, chi, energy.obs, self.pinhole, self.body.limits,
                                    self.refinement, self.likelihood.gate_px)
        return self.after_refinement(energy, chi, info)

    def after_refinement(self, energy: MarkerEnergy, chi: np.ndarray, info: dict | None) -> np.ndarray:
        """The rest of :meth:`after_annealing` once chi is refined (``info``: what
        :func:`refine_pose` said; None: no refinement): offsets learned (the several-people
        tracker refines its people together)."""
        self._refined = None if info is None else RefineTrace(**info)
        self._learn_offsets(energy, chi)
        return chi

    def report(self, energy, n_views, chi, trace, timings) -> StepDiagnostics:
        points = energy.points(chi[None]).astype(np.float64)
        terms = {k: float(v[0]) for k, v in energy.terms_of_points(points).items()}
        reproj = reprojection_errors(points[0], energy.obs, self.pinhole, self.likelihood.gate_px)
        names = tuple(self.landmarks.names)
        report = LandmarkReport(
            names=names, points=points[0], views={n: int(v) for n, v in zip(names, n_views, strict=True)},
            weak=tuple(n for n, w in zip(names, energy.weak, strict=True) if w),
            reprojection_px=float(np.nanmedian(reproj)) if np.isfinite(reproj).any() else float("nan"))
        return StepDiagnostics(energy_terms=terms, anneal=trace, landmarks=report, timings=timings,
                               marker_refine=self._refined)



class MarkerStart(Uncached):
    """The marker tracker's start-up (:meth:`MarkerAPFTracker.initial_estimate`) as an
    :class:`~mocap.trackers.contract.Initializer`; info: its seconds. Never cached."""

    def __init__(self, tracker: MarkerAPFTracker):
        self.tracker = tracker

    def __call__(self, frame: Frame):
        from mocap.trackers.contract import initial_estimate_of

        t = time.perf_counter()
        chi, alpha = self.tracker.initial_estimate(frame)
        return {0: initial_estimate_of(chi, alpha)}, {"seconds": time.perf_counter() - t}
