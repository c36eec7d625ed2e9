"""Choosing a sink from the recording settings (:mod:`mocap.recording.settings`): the Rerun
sink, or none when recording is off."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from mocap.recording.settings import RecordingSettings, recording_settings
from mocap.recording.sink import NullSink


def make_sink(out_dir: Path, settings: RecordingSettings | Mapping | None = None):
    """A sink writing ``out_dir/recording.rrd`` (:class:`RerunSink`), or none when not enabled;
    settings: :class:`RecordingSettings` or the ``recording`` config node (checked either way:
    a bad value is an error whether or not it is used)."""
    if not isinstance(settings, RecordingSettings):
        settings = recording_settings(settings)
    if not settings.enabled:
        return NullSink()
    from mocap.recording.rerun_sink import RerunSink

    return RerunSink(Path(out_dir) / "recording.rrd", settings)
