"""The frame loop, written once (:func:`run_frames`: ``mocap track``, the other tracking commands
and :func:`mocap.track`), and the starts a run can be given (:func:`run_start`): ground truth
plus noise (a controlled experiment), a given pose, or the tracker's own self-initialisation."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from mocap.body.model import BodyModel
from mocap.data.sequence import Sequence
from mocap.threads import thread_budget
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.contract import FrameEstimate, Initializer, Tracker, Uncached, initial_estimate_of

#: on_frame(f, estimate of the frame {person id: estimate}, step seconds)
OnFrame = Callable[[int, FrameEstimate, float], None]


@dataclass(frozen=True)
class TrackResult:
    """A run's tracks: ``tracks`` {person id: {frame: estimate}} (frame 0: the start),
    ``seconds`` (F,) tracking time per frame (step only; frame 0: 0), ``several_people``: the
    tracker's; ``frames``: F; ``live``: per frame, the ids of the people the tracker answered
    for (sorted). ``estimates``: person 0's estimate per frame (a single-person run)."""

    tracks: dict[int, dict[int, Estimate]]
    seconds: list[float]
    several_people: bool = False
    frames: int = 0
    live: list[tuple[int, ...]] = field(default_factory=list)

    @property
    def estimates(self) -> list[Estimate]:
        if self.several_people:
            raise ValueError("a several-people run has no single list of estimates: use result.tracks")
        return [self.tracks[0][f] for f in sorted(self.tracks.get(0, {}))]


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


@dataclass(frozen=True)
class GivenStart(Uncached):
    """A start at a given pose chi (D,) and shape alpha (K,) for person 0; never cached."""

    chi: np.ndarray
    alpha: np.ndarray
    info: dict = field(default_factory=dict)

    def __call__(self, frame: Frame) -> tuple[dict[int, Estimate], dict]:
        return {0: initial_estimate_of(self.chi, self.alpha)}, dict(self.info)


#: the ways a run starts (``init.mode``)
INIT_MODES = ("auto", "gt_noise", "tracker")


@dataclass(frozen=True)
class StartSettings:
    """``init.*``: how a run starts (:func:`run_start`): ``mode`` (``auto``: ``gt_noise`` where
    the data has a ground-truth pose and the tracker follows one person, else ``tracker``), the
    noise of a ground-truth start (degrees on joint angles, metres on the position), the
    self-initialisation's cache folder."""

    mode: str = "auto"
    noise_deg: float = 3.0
    noise_translation: float = 0.02
    cache: str | None = None

    def __post_init__(self):
        if self.mode not in INIT_MODES:
            raise ValueError(f"init.mode must be one of {INIT_MODES}, got {self.mode!r}")


def require_pose(seq: Sequence) -> None:
    """A one-line ValueError when ``seq`` has no ground-truth pose to start from."""
    if seq.gt is None or seq.gt.chi is None:
        raise ValueError(f"sequence {seq.name!r} has no ground-truth pose chi: use init.mode=tracker")


def run_start(mode: str, tracker: Tracker, body: BodyModel, seq: Sequence, rng: np.random.Generator,
              noise_deg: float = 3.0, noise_translation: float = 0.02, cache=None) -> Initializer:
    """The start of a run: ``gt_noise``, the sequence's ground truth of frame 0 plus noise
    (:func:`noisy_initial_pose`, drawn from ``rng`` now) with its shape; ``tracker``, the
    tracker's self-initialisation (cached in the folder ``cache``); ``auto``, gt_noise where the
    sequence has a ground-truth pose and the tracker follows one person, else tracker. One-line
    ValueErrors for a start the data or tracker cannot give."""
    if mode == "auto":
        has_pose = seq.gt is not None and seq.gt.chi is not None
        mode = "gt_noise" if has_pose and not tracker.several_people else "tracker"
    if mode == "gt_noise":
        require_pose(seq)
        if tracker.several_people:
            raise ValueError(f"tracker {tracker.name!r} initialises every person itself: run with "
                             f"init.mode=tracker (got init.mode={mode})")
        return GivenStart(noisy_initial_pose(body, seq.gt.chi[0], rng, noise_deg, noise_translation),
                          seq.gt.alpha)
    if mode == "tracker":
        if cache and tracker.several_people:
            raise ValueError(f"tracker {tracker.name!r} does not use init.cache (got {cache!r}): "
                             "leave it null")
        start = tracker.initializer(cache)
        if start is None:
            raise ValueError(f"tracker {tracker.name!r} cannot initialise itself: use init.mode=gt_noise")
        return start
    raise ValueError(f"init.mode must be one of {INIT_MODES}, got {mode!r}")


def frame_of(seq: Sequence, f: int) -> Frame:
    return Frame(index=f,
                 masks=None if seq.masks is None else seq.masks[f],
                 images=None if seq.images is None else seq.images[f],
                 detections=None if seq.detections is None else seq.detections.select(f))


def run_frames(tracker: Tracker, seq: Sequence, initial: FrameEstimate, frames: int | None = None,
               on_frame: OnFrame | None = None, threads: int | None = None) -> TrackResult:
    """Start ``tracker`` on frame 0 from ``initial`` (its estimate is frame 0's) and track frames
    1..F-1 (F: ``frames``, at most the sequence's; None: all); ``on_frame`` sees each frame's
    estimate as it comes. threads: thread budget of the numeric kernels while tracking
    (:func:`mocap.threads.thread_budget`; None: the libraries' defaults)."""
    with thread_budget(threads):
        F = seq.num_frames if frames is None else min(frames, seq.num_frames)
        first = dict(tracker.begin(frame_of(seq, 0), initial))
        tracks: dict[int, dict[int, Estimate]] = {pid: {0: est} for pid, est in first.items()}
        seconds = [0.0]
        live = [tuple(sorted(first))]
        if on_frame is not None:
            on_frame(0, first, seconds[0])
        for f in range(1, F):
            t = time.perf_counter()
            out = dict(tracker.track(frame_of(seq, f)))
            seconds.append(time.perf_counter() - t)
            for pid, est in out.items():
                if not np.all(np.isfinite(est.chi)):
                    who = f" of person {pid}" if tracker.several_people else ""
                    raise FloatingPointError(f"{tracker.name}: non-finite pose{who} at frame {f}")
                tracks.setdefault(pid, {})[f] = est
            live.append(tuple(sorted(out)))
            if on_frame is not None:
                on_frame(f, out, seconds[-1])
        final = tracker.final_tracks(tracks)
    return TrackResult({pid: dict(t) for pid, t in final.items()}, seconds, tracker.several_people, F, live)


def track_sequence(tracker: Tracker, seq: Sequence, init_chi: np.ndarray, alpha: np.ndarray,
                   frames: int | None = None,
                   on_frame: Callable[[int, Estimate, float], None] | None = None,
                   threads: int | None = None) -> TrackResult:
    """:func:`run_frames` of a single-person tracker started at pose ``init_chi`` (D,) and shape
    ``alpha`` (K,); ``on_frame(f, estimate, seconds)`` sees person 0's estimates."""
    each = None if on_frame is None else (lambda f, out, s: on_frame(f, out[0], s))
    return run_frames(tracker, seq, {0: initial_estimate_of(init_chi, alpha)}, frames, each, threads)
