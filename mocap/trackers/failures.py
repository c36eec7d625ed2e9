"""Injected tracking failures, for recovery experiments (``mocap recovery``).

:class:`FailureInjection` is a tracker that passes frames on to another one and injects
failures on the way, through the tracker interface only:

- :class:`FrameSkip`: a stretch of frames never reaches the tracker (dropped video); the
  output holds the last estimate there, and the tracker sees the next frame as if it followed
  the last one it saw.
- :class:`Perturbation`: before a frame, the tracker is restarted (``Tracker.initialize``,
  the one documented way to put a tracker at a pose) from its last estimate moved far away:
  some joint angles by +-``degrees``, the root by ``translation``. Restarting also forgets
  the motion history, as a tracker that lost its subject would.

Injected frames carry :class:`mocap.trackers.diagnostics.Injection` in their diagnostics.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mocap.body.model import BodyModel
from mocap.trackers.base import Estimate, Frame, Tracker
from mocap.trackers.contract import OnePerson
from mocap.trackers.diagnostics import Injection, StepDiagnostics


@dataclass(frozen=True)
class FrameSkip:
    """Frames ``at`` .. ``at + count - 1`` are dropped."""

    at: int
    count: int

    def __post_init__(self):
        if self.at < 1 or self.count < 1:
            raise ValueError(f"a frame skip needs at >= 1 and count >= 1, got {self.at}, {self.count}")

    @property
    def frames(self) -> range:
        return range(self.at, self.at + self.count)

    @property
    def resumes_at(self) -> int:
        """The first frame the tracker sees again."""
        return self.at + self.count


@dataclass(frozen=True)
class Perturbation:
    """Before frame ``at``: ``dofs`` joint angles (drawn among the non-root DOFs) move by
    +-``degrees`` (random signs) and the root by ``translation`` (m, world)."""

    at: int
    degrees: float = 30.0
    dofs: int = 6
    translation: tuple[float, float, float] = (0.1, -0.1, 0.0)

    def __post_init__(self):
        if self.at < 1:
            raise ValueError(f"a perturbation needs at >= 1, got {self.at}")

    def apply(self, body: BodyModel, chi: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The perturbed pose (D,), inside the body's limits."""
        bad = np.asarray(chi, np.float64).copy()
        idx = rng.choice(np.arange(6, body.num_dofs), size=min(self.dofs, body.num_dofs - 6), replace=False)
        bad[idx] += np.deg2rad(self.degrees) * rng.choice([-1, 1], size=len(idx))
        bad[:3] += np.asarray(self.translation, np.float64)
        return np.clip(bad, body.limits[:, 0], body.limits[:, 1])


class FailureInjection(OnePerson):
    """Wraps ``tracker``: same interface, same name, its sequence check and final tracks (a
    smoothed track stays smoothed under injection); ``skips`` and ``perturbations`` happen
    at their frames (by ``Frame.index``); ``rng`` draws the perturbed DOFs and signs."""

    def __init__(self, tracker: Tracker, body: BodyModel, skips: Sequence[FrameSkip] = (),
                 perturbations: Sequence[Perturbation] = (), rng: np.random.Generator | None = None):
        self.tracker, self.body = tracker, body
        self.name = tracker.name
        self.skipped = {f for s in skips for f in s.frames}
        self.perturbations = {p.at: p for p in perturbations}
        if len(self.perturbations) != len(perturbations):
            raise ValueError("two perturbations at the same frame")
        if self.skipped & self.perturbations.keys():
            raise ValueError("a perturbation at a skipped frame would never reach the tracker")
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.last: Estimate | None = None

    def check_sequence(self, seq) -> None:
        self.tracker.check_sequence(seq)

    @property
    def revises_tracks(self) -> bool:
        """The wrapped tracker's: its final tracks (a smoothed track) are the run's."""
        return self.tracker.revises_tracks

    def final_tracks(self, tracks):
        return self.tracker.final_tracks(tracks)

    def initialize(self, chi: np.ndarray, alpha: np.ndarray) -> None:
        self.tracker.initialize(chi, alpha)
        self.last = Estimate(chi=np.asarray(chi, np.float64), alpha=np.asarray(alpha))

    def step(self, frame: Frame) -> Estimate:
        if self.last is None:
            raise RuntimeError("initialize() the tracker before step()")
        if frame.index in self.skipped:
            return Estimate(chi=self.last.chi, alpha=self.last.alpha,
                            diagnostics=StepDiagnostics(injection=Injection(skipped=True)))
        p = self.perturbations.get(frame.index)
        if p is not None:
            self.tracker.initialize(p.apply(self.body, self.last.chi, self.rng), self.last.alpha)
        est = self.tracker.step(frame)
        if p is not None:
            est = dataclasses.replace(est, diagnostics=dataclasses.replace(
                est.diagnostics, injection=Injection(perturbed=True)))
        self.last = est
        return est
