"""Choosing a sink from configuration."""

from __future__ import annotations

from pathlib import Path

from mocap.recording.sink import NullSink


def make_sink(out_dir: Path, enabled: bool = True, every: int = 1, particles: bool = True,
              images: bool = True, scale: float = 0.25):
    """A sink writing ``out_dir/recording.rrd`` (:class:`RerunSink`), or none when not enabled;
    the settings are checked either way (a bad value is an error whether or not it is used)."""
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ValueError(f"recording.every must be an integer >= 1, got {every!r}")
    if not enabled:
        return NullSink()
    from mocap.recording.rerun_sink import RerunSink

    return RerunSink(Path(out_dir) / "recording.rrd", every=every, particles=particles,
                     images=images, scale=scale)
