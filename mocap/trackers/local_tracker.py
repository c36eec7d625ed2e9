"""The local tracker (``local``): contour (+ SIFT) correspondences and linearised twists
(Zhang et al. 2013, Sec. 4.1), started each frame from a constant-velocity prediction."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy.smoothness import predict_constant_velocity
from mocap.local.contour import ContourMatcher, observed_contours
from mocap.local.misalignment import MisalignmentDetector
from mocap.local.optimize import optimize_pose
from mocap.local.sift import SiftTracker
from mocap.local.solver import PointLines, merge  # noqa: F401  (merge: re-exported)
from mocap.settings import fields_of, with_overrides
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.contract import Needs, OnePerson
from mocap.trackers.diagnostics import LocalTrace, Misalignment, ShapeUpdate, StepDiagnostics
from mocap.trackers.init_cache import SilhouetteInitialisation
from mocap.trackers.shape_search import refine_shape, shifted
from mocap.trackers.smoothing import filter_pad, smooth_track
from mocap.trackers.tracker_settings import InitSettings, LocalSettings, LocalStepSettings, TrackSmoothing


class LocalTracker(SilhouetteInitialisation, OnePerson):
    """Local optimisation only: fast, accurate while the motion is slow, cannot recover.

    settings: :class:`LocalSettings` (or the local step alone, :class:`LocalStepSettings`,
    with the default initialisation); keyword ``overrides`` update them key by key
    (e.g. ``sift={"enabled": False}``). ``settings.shape``: the shape refinement (off by
    default): every ``every`` frames the shape is searched again on recent keyframes, their
    poses held (the estimate of that frame onwards carries the new shape)."""

    needs = Needs(masks=True)

    def __init__(self, body: BodyModel, rig: Rig, settings: LocalStepSettings | None = None,
                 name: str = "local", rng: np.random.Generator | None = None, **overrides):
        settings = with_overrides(LocalSettings() if settings is None else settings, overrides)
        self.body, self.rig, self.name = body, rig, name
        self.tracker_settings = self.local_settings = settings
        self.shape_settings = settings.shape
        self.init_rng = rng if rng is not None else np.random.default_rng(0)
        self.init_settings = getattr(settings, "initialization", None) or InitSettings()
        self.iterations, self.tolerance = settings.iterations, settings.tolerance
        self.damping = settings.damping
        self.energy_tolerance = settings.energy_tolerance
        self.active_limits = settings.active_limits
        self.prediction_damping = settings.prediction_damping
        self.fps: float | None = None       # the sequence's frame rate (check_sequence): smoothing's
        self.shaped = None
        self.history: list[np.ndarray] = []

    def initialize(self, chi: np.ndarray, alpha: np.ndarray) -> None:
        chi = self.checked_pose(chi)
        self.set_shape(alpha)
        s = self.local_settings
        self.matcher = ContourMatcher(self.body, self.rig, **fields_of(s.contour, type(s.contour)))
        self.sift = SiftTracker(self.body, self.rig, **fields_of(s.sift, type(s.sift), skip=("enabled",))) \
            if s.sift.enabled else None
        self.detector = MisalignmentDetector(self.body, self.rig,
                                             **fields_of(s.misalignment, type(s.misalignment)))
        self.history = [chi]
        self.last_images = None
        self.keyframes: deque = deque(maxlen=self.shape_settings.keyframes)   # (index, chi, masks)

    @property
    def smoothing(self) -> TrackSmoothing:
        """The finished track's smoothing (``tracker_settings.smoothing``; off where the settings
        have none)."""
        return getattr(self.tracker_settings, "smoothing", None) or TrackSmoothing()

    @property
    def revises_tracks(self) -> bool:
        """Whether :meth:`final_tracks` changes the estimates the frames were answered with (the
        run then records the frames from the final tracks)."""
        return self.smoothing.enabled

    def check_sequence(self, seq) -> None:
        """As :class:`OnePerson`'s; keeps the sequence's frame rate (the smoothing's time base)."""
        super().check_sequence(seq)
        self.fps = float(seq.fps)

    def final_tracks(self, tracks):
        """The tracks as tracked, or with ``smoothing`` on, each person's poses smoothed
        (:func:`mocap.trackers.smoothing.smooth_track`, at the frame rate of the sequence given
        to :meth:`check_sequence`)."""
        pad = filter_pad(self.smoothing.order)
        if not self.smoothing.enabled or all(len(t) <= pad for t in tracks.values()):
            return tracks               # off, or too short to smooth
        if self.fps is None:
            raise RuntimeError(f"tracker {self.name!r}: smoothing needs the frame rate: call "
                               "check_sequence(seq) before tracking")
        return {pid: smooth_track(t, self.body.limits, self.fps, self.smoothing) for pid, t in tracks.items()}

    def set_shape(self, alpha: np.ndarray, joint_offsets: np.ndarray | None = None) -> None:
        """Track on with the shape ``alpha`` (K,) (and rest-joint corrections ``joint_offsets``
        (J, 3), None: none; :meth:`mocap.body.model.BodyModel.shaped`)."""
        self.shaped = self.body.shaped(alpha, joint_offsets)

    def refine_shape(self, frame: Frame, chi: np.ndarray, aligned: bool = True
                     ) -> tuple[np.ndarray, ShapeUpdate | None]:
        """Keep this frame as a keyframe when it falls on the stride and the misalignment check
        flagged no limb (``aligned``: a shape fitted to a wrong pose would make up for it) and,
        every ``every`` frames, search the shape on the keyframes (:func:`refine_shape`); returns
        this frame's pose (moved by the shift that came with a kept shape) and the report (None:
        no search this frame)."""
        s = self.shape_settings
        if not s.every or frame.masks is None:
            return chi, None
        due = frame.index % s.every == 0
        if aligned and (frame.index % s.stride == 0 or due):
            self.keyframes.append((frame.index, chi, frame.masks))
        if not due or len(self.keyframes) < 2:
            return chi, None
        frames, chis, masks = zip(*self.keyframes, strict=True)
        found = refine_shape(self.body, self.rig, self.shaped.alpha, np.stack(chis), list(masks), frames,
                             s, self.init_rng)
        if found.accepted:
            self.set_shape(found.alpha)
            chi = shifted(chi, found.shift)
            self.history = [shifted(c, found.shift) for c in self.history]
            self.keyframes = deque(((f, shifted(c, found.shift), m) for f, c, m in self.keyframes),
                                   maxlen=s.keyframes)
        return chi, ShapeUpdate(found.energy_before, found.energy_after, found.accepted,
                                tuple(float(x) for x in found.shift), found.frames)

    def finish_step(self, frame: Frame, chi: np.ndarray, verts: np.ndarray, aligned: bool,
                    timings: dict) -> tuple[np.ndarray, ShapeUpdate | None]:
        """The end of every step: the shape refinement (:meth:`refine_shape`; its time goes into
        ``timings``), then SIFT remembers this frame's body and the pose joins the history.
        ``verts``: the body posed at ``chi``; returns the frame's pose and the shape report."""
        t = time.perf_counter()
        chi, shape = self.refine_shape(frame, chi, aligned)
        if shape is not None:
            timings["shape"] = time.perf_counter() - t
            verts = self.shaped.pose(chi).vertices[0]
        if self.sift is not None and frame.images is not None:
            self.sift.remember(frame.images, verts.astype(np.float64))
        self.history = (self.history + [chi])[-3:]
        return chi, shape

    def local_step(self, frame: Frame, start: np.ndarray, free: np.ndarray | None = None,
                   extra: Callable[[np.ndarray], PointLines] | None = None,
                   iterations: int | None = None) -> tuple[np.ndarray, LocalTrace]:
        """Optimise from ``start`` on this frame; the trace holds the correspondence counts.
        ``extra``: pose (D,) -> more correspondences beside the contours' (the hybrid's keypoints);
        ``iterations``: the optimiser's (None: the tracker's ``iterations``)."""
        if frame.masks is None:
            raise ValueError(f"frame {frame.index}: the local tracker needs silhouette masks")
        obs = observed_contours(frame.masks)
        sift_pairs = sift_info = None
        if self.sift is not None:
            if frame.images is None:
                sift_info = "no images in this sequence: contour correspondences only"
            else:
                prev_verts = self.shaped.pose(self.history[-1]).vertices[0].astype(np.float64)
                sift_pairs, sift_info = self.sift.match(frame.images, prev_verts)

        def correspond(verts: np.ndarray):
            corr, info = self.matcher(verts, obs)
            if sift_pairs is not None:
                corr = merge([corr, sift_pairs.correspondences(verts)])
            return corr, info

        iterations = self.iterations if iterations is None else iterations
        chi, opt = optimize_pose(self.shaped, start, correspond, iterations, self.tolerance,
                                 self.damping, free=free, energy_tolerance=self.energy_tolerance,
                                 extra=extra, active_limits=self.active_limits)
        return chi, LocalTrace.from_optimizer(opt, sift_info)

    def step(self, frame: Frame) -> Estimate:
        if self.shaped is None:
            raise RuntimeError("initialize() the tracker before step()")
        t0 = time.perf_counter()
        start = predict_constant_velocity(self.history[-2:], self.prediction_damping)
        chi, local = self.local_step(frame, start)
        t1 = time.perf_counter()
        verts = self.shaped.pose(chi).vertices[0]
        limbs = self.detector(verts, frame.masks)
        t2 = time.perf_counter()
        timings = {"local": t1 - t0, "misalignment": t2 - t1}
        chi, shape = self.finish_step(frame, chi, verts, not limbs.names, timings)
        return Estimate(chi=chi, alpha=self.shaped.alpha, diagnostics=StepDiagnostics(
            local=local, misalignment=Misalignment.of(limbs), shape=shape, timings=timings))
