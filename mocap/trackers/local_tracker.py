"""The local tracker (``local``): contour (+ SIFT) correspondences and linearised twists
(Zhang et al. 2013, Sec. 4.1), started each frame from a constant-velocity prediction."""

from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy.smoothness import predict_constant_velocity
from mocap.local.contour import ContourMatcher, observed_contours
from mocap.local.misalignment import MisalignmentDetector
from mocap.local.optimize import optimize_pose
from mocap.local.sift import SiftTracker
from mocap.local.solver import PointLines
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.diagnostics import LocalTrace, Misalignment, StepDiagnostics
from mocap.trackers.initialization import InitSettings, SilhouetteInitialisation


def merge(parts: list[PointLines]) -> PointLines:
    parts = [p for p in parts if len(p)]
    if not parts:
        z = np.zeros((0, 3))
        return PointLines(z, np.zeros(0, int), z, z, np.zeros(0))
    return PointLines(*(np.concatenate([getattr(p, f) for p in parts])
                        for f in ("points", "limbs", "d", "m", "weights")))


class LocalTracker(SilhouetteInitialisation):
    """Local optimisation only: fast, accurate while the motion is slow, cannot recover."""

    def __init__(self, body: BodyModel, rig: Rig, iterations: int = 10, tolerance: float = 1e-4,
                 damping: float = 1e-3, prediction_damping: float = 1.0,
                 contour: Mapping | None = None, sift: Mapping | None = None,
                 misalignment: Mapping | None = None, name: str = "local",
                 rng: np.random.Generator | None = None, initialization: Mapping | None = None,
                 energy_tolerance: float = 0.0):
        self.body, self.rig, self.name = body, rig, name
        self.init_rng = rng if rng is not None else np.random.default_rng(0)
        self.init_settings = InitSettings(**dict(initialization or {}))
        self.iterations, self.tolerance, self.damping = iterations, tolerance, damping
        self.energy_tolerance = energy_tolerance
        self.prediction_damping = prediction_damping
        self.contour_cfg = dict(contour or {})
        self.sift_cfg = dict(sift or {"enabled": True})
        self.misalignment_cfg = dict(misalignment or {})
        self.shaped = None
        self.history: list[np.ndarray] = []

    def initialize(self, chi: np.ndarray, alpha: np.ndarray) -> None:
        chi = self.checked_pose(chi)
        self.shaped = self.body.shaped(alpha)
        self.matcher = ContourMatcher(self.body, self.rig, **self.contour_cfg)
        sift = dict(self.sift_cfg)
        self.sift = SiftTracker(self.body, self.rig, **{k: v for k, v in sift.items() if k != "enabled"}) \
            if sift.pop("enabled", True) else None
        self.detector = MisalignmentDetector(self.body, self.rig, **self.misalignment_cfg)
        self.history = [chi]
        self.last_images = None

    def local_step(self, frame: Frame, start: np.ndarray,
                   free: np.ndarray | None = None) -> tuple[np.ndarray, LocalTrace]:
        """Optimise from ``start`` on this frame; the trace holds the correspondence counts."""
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

        chi, opt = optimize_pose(self.shaped, start, correspond, self.iterations, self.tolerance,
                                 self.damping, free=free, energy_tolerance=self.energy_tolerance)
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
        if self.sift is not None and frame.images is not None:
            self.sift.remember(frame.images, verts.astype(np.float64))
        self.history = (self.history + [chi])[-3:]
        return Estimate(chi=chi, alpha=self.shaped.alpha, diagnostics=StepDiagnostics(
            local=local, misalignment=Misalignment.of(limbs),
            timings={"local": t1 - t0, "misalignment": t2 - t1}))
