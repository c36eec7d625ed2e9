"""Running a tracker over a sequence, and the initial pose of a controlled experiment."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mocap.body.model import BodyModel
from mocap.data.sequence import Sequence
from mocap.threads import thread_budget
from mocap.trackers.base import Estimate, Frame, Tracker
from mocap.trackers.diagnostics import StepDiagnostics


@dataclass(frozen=True)
class TrackResult:
    estimates: list[Estimate]
    seconds: list[float]          # tracking time per frame (step only)


def noisy_initial_pose(body: BodyModel, chi: np.ndarray, rng: np.random.Generator,
                       noise_deg: float, noise_translation: float) -> np.ndarray:
    """Ground truth plus Gaussian noise on joint angles and position, inside the limits."""
    chi = np.asarray(chi, np.float64).copy()
    if not np.all(np.isfinite(chi)):
        raise ValueError("the initial pose contains NaN or inf")
    chi[:3] += rng.normal(0, noise_translation, 3)
    chi[6:] += rng.normal(0, np.deg2rad(noise_deg), body.num_dofs - 6)
    lo, hi = body.limits[:, 0], body.limits[:, 1]
    return np.clip(chi, lo, hi)


def search_budget(tracker: Tracker) -> dict:
    """Particles, layers and energy terms of a tracker's global search (the APF of a hybrid
    tracker; zeros for a tracker without one), as the tracker holds them."""
    settings, weights = getattr(tracker, "settings", None), getattr(tracker, "weights", None)
    return {"particles": settings.particles if settings else 0,
            "layers": settings.layers if settings else 0,
            "energy_terms": list(weights.terms) if weights else []}


def frame_of(seq: Sequence, f: int) -> Frame:
    return Frame(index=f,
                 masks=None if seq.masks is None else seq.masks[f],
                 images=None if seq.images is None else seq.images[f],
                 detections=None if seq.detections is None else seq.detections.select(f))


def track_sequence(tracker: Tracker, seq: Sequence, init_chi: np.ndarray, alpha: np.ndarray,
                   frames: int | None = None,
                   on_frame: Callable[[int, Estimate, float], None] | None = None,
                   threads: int | None = None) -> TrackResult:
    """Initialise on frame 0 (its estimate is the initial pose) and track frames 1..F-1.

    threads: thread budget of the numeric kernels while tracking (BLAS / OpenMP, numba,
    OpenCV; :func:`mocap.threads.thread_budget`); None leaves the libraries' defaults.
    """
    with thread_budget(threads):
        return _track(tracker, seq, init_chi, alpha, frames, on_frame)


def _track(tracker: Tracker, seq: Sequence, init_chi: np.ndarray, alpha: np.ndarray,
           frames: int | None, on_frame: Callable[[int, Estimate, float], None] | None) -> TrackResult:
    F = seq.num_frames if frames is None else min(frames, seq.num_frames)
    tracker.initialize(init_chi, alpha)
    estimates = [Estimate(chi=np.asarray(init_chi, np.float64), alpha=np.asarray(alpha),
                          diagnostics=StepDiagnostics(initial=True))]
    seconds = [0.0]
    if on_frame is not None:
        on_frame(0, estimates[0], 0.0)
    for f in range(1, F):
        t = time.perf_counter()
        est = tracker.step(frame_of(seq, f))
        seconds.append(time.perf_counter() - t)
        if not np.all(np.isfinite(est.chi)):
            raise FloatingPointError(f"{tracker.name}: non-finite pose at frame {f}")
        estimates.append(est)
        if on_frame is not None:
            on_frame(f, est, seconds[-1])
    return TrackResult(estimates, seconds)
