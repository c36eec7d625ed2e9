"""A tracking run's own settings (what ``conf/tracking.yaml`` documents beside the body,
data and tracker): frozen dataclasses, the only place their defaults are written, built and
checked once from the run's configuration (:meth:`RunSettings.from_config`; each error one line
naming the setting, its value and what is allowed).

    seed, frames, threads            the data/tracker seed (an int >= 0), frames to track (an int
                                     >= 1, at most the data's; None or "all": all), thread budget
    init.mode                        gt_noise (ground truth + noise) | tracker (self-initialised)
    init.noise_deg, init.noise_translation, init.cache
    recording.*                      :func:`mocap.recording.factory.recording_settings`
    motion.vertices                  keep the posed mesh per frame in motion.npz
    oracle.enabled, oracle.cache     fit the oracle (our body fitted to the true joints), where to cache
                                     it (:class:`mocap.eval.run_metrics.OracleSettings`)
    skip_complete, resume_on_change  resuming a sweep (:mod:`mocap.run_folder.resume`)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from mocap.eval.run_metrics import OracleSettings, oracle_settings
from mocap.recording.settings import RecordingSettings, recording_settings
from mocap.trackers.run import INIT_MODES, StartSettings  # noqa: F401  (INIT_MODES: re-exported)

RESUME_ON_CHANGE = ("rerun", "fail")


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


@dataclass(frozen=True)
class MotionSettings:
    """``motion.*``: what motion.npz keeps beyond the poses."""

    vertices: bool = False


@dataclass(frozen=True)
class RunSettings:
    """A run's own settings (see the module docstring). ``frames`` None: every frame."""

    seed: int = 0
    frames: int | None = None
    threads: int | str | None = "auto"
    init: StartSettings = field(default_factory=StartSettings)
    recording: RecordingSettings = field(default_factory=RecordingSettings)
    motion: MotionSettings = field(default_factory=MotionSettings)
    oracle: OracleSettings = field(default_factory=OracleSettings)
    skip_complete: bool = False
    resume_on_change: str = "rerun"

    def __post_init__(self):
        if not _is_int(self.seed) or self.seed < 0:
            raise ValueError(f"setting seed = {self.seed!r} is not allowed (an integer >= 0)")
        if self.frames is not None and (not _is_int(self.frames) or self.frames < 1):
            raise ValueError(f"setting frames = {self.frames!r} is out of range (an integer >= 1, or all / "
                             "null for every frame of the data)")
        if self.resume_on_change not in RESUME_ON_CHANGE:
            raise ValueError(f"setting resume_on_change = {self.resume_on_change!r} is not allowed (one of "
                             f"{', '.join(RESUME_ON_CHANGE)})")

    @classmethod
    def from_config(cls, config: Mapping) -> RunSettings:
        """The settings of a run's configuration (plain values; keys of other nodes, such as
        ``body``, ``data``, ``tracker``, are not the run's and are left alone). A key left out
        takes the default."""
        given = {k: config[k] for k in ("seed", "threads", "skip_complete", "resume_on_change")
                 if k in config}
        frames = config.get("frames")
        if frames is not None and not (isinstance(frames, str) and frames == "all"):
            given["frames"] = frames
        cls(**given)            # seed and frames first: the order the errors are checked in
        init = {k: v for k, v in dict(config.get("init") or {}).items() if k in _INIT_KEYS}
        motion = dict(config.get("motion") or {})
        return cls(**given, init=StartSettings(**init), recording=recording_settings(config.get("recording")),
                   motion=MotionSettings(vertices=bool(motion.get("vertices", False))),
                   oracle=oracle_settings(config.get("oracle")))


_INIT_KEYS = ("mode", "noise_deg", "noise_translation", "cache")


def check_settings(config: Mapping) -> int | None:
    """The run's own settings, checked before any work; returns the frames to track (None:
    all). Each error names the setting, its value and what is allowed."""
    return RunSettings.from_config(config).frames
