"""The recording interface the experiment harness talks to. Trackers never see it: they
return diagnostics as data, and the harness hands them to a sink.

``NullSink`` records nothing; :class:`mocap.recording.rerun_sink.RerunSink` writes a Rerun
``.rrd`` file. Both follow :class:`RunSink`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from mocap.body.model import BodyModel
from mocap.data.sequence import Sequence
from mocap.trackers.base import Estimate, Frame


@dataclass(frozen=True)
class RunInfo:
    """What a run was: its resolved config as YAML text and metadata (git revision, seed,
    config hash, tracker, data)."""

    config_yaml: str
    metadata: dict


class RunSink(Protocol):
    def start(self, info: RunInfo, body: BodyModel, seq: Sequence) -> None: ...

    def frame(self, frame: Frame, estimate: Estimate, joints: np.ndarray,
              vertices: np.ndarray, truth_joints: np.ndarray | None,
              error_mm: float | None, seconds: float) -> None: ...

    def people_frame(self, frame: Frame, people: dict, truth: np.ndarray | None, seconds: float) -> None: ...

    def finish(self, metrics: dict | None, failed: bool = False) -> None: ...


class NullSink:
    """Records nothing (recording switched off)."""

    path = None

    def start(self, info: RunInfo, body: BodyModel, seq: Sequence) -> None:
        pass

    def frame(self, frame, estimate, joints, vertices, truth_joints, error_mm, seconds) -> None:
        pass

    def people_frame(self, frame, people, truth, seconds) -> None:
        pass

    def finish(self, metrics: dict | None, failed: bool = False) -> None:
        pass
