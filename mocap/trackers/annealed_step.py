"""The step of the annealed trackers (silhouette APF, marker APF), written once: predict,
build this frame's energy, search, report. A tracker supplies the parts."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from mocap.trackers.apf import AnnealTrace
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.diagnostics import StepDiagnostics


class AnnealedStep:
    """Mixin: ``step(frame)`` from ``predict() -> (D,)``, ``frame_energy(frame, predicted)
    -> (energy, context)``, ``search(energy, predicted) -> (chi, AnnealTrace)`` and
    ``report(energy, context, chi, trace, timings) -> StepDiagnostics``. Needs ``shaped``
    and ``history`` (the last estimates, newest last)."""

    shaped: Any
    history: list[np.ndarray]

    def step(self, frame: Frame) -> Estimate:
        if self.shaped is None:
            raise RuntimeError("initialize() the tracker before step()")
        t0 = time.perf_counter()
        predicted = self.predict()
        energy, context = self.frame_energy(frame, predicted)
        t1 = time.perf_counter()
        chi, trace = self.search(energy, predicted)
        t2 = time.perf_counter()
        self.history = [*self.history[-2:], chi]
        timings = {"observation": t1 - t0, "search": t2 - t1}
        return Estimate(chi=chi, alpha=self.shaped.alpha,
                        diagnostics=self.report(energy, context, chi, trace, timings))

    def report(self, energy, context, chi: np.ndarray, trace: AnnealTrace,
               timings: dict[str, float]) -> StepDiagnostics:
        terms = {k: float(v[0]) for k, v in energy.terms(chi[None]).items()}
        return StepDiagnostics(energy_terms=terms, anneal=trace, timings=timings)
