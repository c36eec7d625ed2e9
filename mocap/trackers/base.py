"""The tracker interface and the data that flows through it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from mocap.data.sequence import Detections
from mocap.trackers.diagnostics import StepDiagnostics


@dataclass(frozen=True)
class Frame:
    """One frame's observations. masks: (C, H, W) bool; images: (C, H, W, 3) uint8;
    detections: this frame's 2D detections. Any may be None."""

    index: int
    masks: np.ndarray | None = None
    images: np.ndarray | None = None
    detections: Detections | None = None


@dataclass(frozen=True)
class Estimate:
    """A tracker's answer for one frame: pose chi (D,), shape alpha (K,), what the step
    reports (:class:`mocap.trackers.diagnostics.StepDiagnostics`: energies per term, annealing
    layers, local iterations, decisions, timings in seconds) and the body's rest-joint
    corrections ``joint_offsets`` (J, 3) metres (None: none, the shape's own skeleton;
    :meth:`mocap.body.model.BodyModel.shaped`)."""

    chi: np.ndarray
    alpha: np.ndarray
    diagnostics: StepDiagnostics = field(default_factory=StepDiagnostics)
    joint_offsets: np.ndarray | None = None


class Tracker(Protocol):
    """A tracker of one person: set up from a pose and shape, then one estimate per frame (what
    the run asks of every tracker is :class:`mocap.trackers.contract.Tracker`; a single-person
    tracker gets it from :class:`mocap.trackers.contract.OnePerson`)."""

    name: str

    def initialize(self, chi: np.ndarray, alpha: np.ndarray) -> None: ...

    def step(self, frame: Frame) -> Estimate: ...
