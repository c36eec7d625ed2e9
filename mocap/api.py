"""The Python API: track a sequence with a named tracker, no Hydra and no repository needed.

    import mocap
    body = mocap.load_body("paper22")
    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=10)
    result = mocap.track(seq, tracker="hybrid", body=body, seed=0)
    poses = [e.chi for e in result.estimates]

The trackers are the presets of :data:`mocap.trackers.presets.PRESETS` (``tracker=<name>`` on
the command line); keyword arguments override their settings exactly as ``tracker.<key>=...``
does on the command line.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mocap.body import BodyModel, load_body
from mocap.data.sequence import Sequence
from mocap.data.source_settings import SyntheticSource
from mocap.trackers.contract import Tracker
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import (
    INIT_MODES,
    GivenStart,
    StartSettings,
    TrackResult,
    frame_of,
    run_frames,
    run_start,
)


def synthetic_sequence(body: BodyModel, cameras: str = SyntheticSource.cameras,
                       motion: str = SyntheticSource.motion, frames: int = SyntheticSource.frames,
                       fps: float = SyntheticSource.fps, seed: int = SyntheticSource.seed,
                       **options) -> Sequence:
    """A synthetic sequence with ground truth (settings and defaults:
    :class:`mocap.data.source_settings.SyntheticSource`); cameras: a preset name
    (:mod:`mocap.presets`) or a calibration file."""
    from mocap.data.sources import synthetic_sequence as make

    return make(body=body, cameras=cameras, motion=motion, frames=frames, fps=fps, seed=seed, **options)


def track(sequence: Sequence, tracker: str | Callable[..., Tracker] = "hybrid", *,
          body: BodyModel | None = None, seed: int = 0,
          init: str | np.ndarray = "auto", alpha: np.ndarray | None = None, frames: int | None = None,
          noise_deg: float = StartSettings.noise_deg,
          noise_translation: float = StartSettings.noise_translation, **settings) -> TrackResult:
    """Track ``sequence`` with the tracker named ``tracker`` (a preset, or a tracker factory of
    one's own, ``tracker(body=, rig=, rng=, **settings)`` -> a
    :class:`mocap.trackers.contract.Tracker`) and return its tracks (person id ->
    {frame: estimate}; ``result.estimates``: one per frame of a single-person tracker, frame 0
    the initial pose) and step times, as ``mocap track`` does (the same start and frame loop).

    init: a pose (D,) (then ``alpha`` (K,) is the shape, default the mean); ``"gt_noise"``:
    ground truth plus noise (``noise_deg`` on angles, ``noise_translation`` m); ``"tracker"``:
    the tracker initialises itself from frame 0; ``"auto"``: gt_noise when the sequence has
    a ground-truth pose and the tracker follows one person, else tracker. The randomness is that
    of ``mocap track`` with the same seed.
    """
    body = body if body is not None else load_body("paper22")
    rng = np.random.default_rng(seed)
    build = (lambda **kw: make_tracker(tracker, **kw)) if isinstance(tracker, str) else tracker
    t = build(body=body, rig=sequence.rig, rng=np.random.default_rng([seed, 1]), **settings)
    t.check_sequence(sequence)
    if isinstance(init, str):
        if init not in INIT_MODES:
            raise ValueError(f"init must be 'auto', 'gt_noise', 'tracker' or a pose, got {init!r}")
        start = run_start(init, t, body, sequence, rng, noise_deg, noise_translation)
    else:
        start = GivenStart(np.asarray(init, np.float64),
                           np.zeros(body.num_shape) if alpha is None else np.asarray(alpha))
    initial, _ = start(frame_of(sequence, 0))
    return run_frames(t, sequence, initial, frames)
