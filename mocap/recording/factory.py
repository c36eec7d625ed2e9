"""Choosing a sink from configuration."""

from __future__ import annotations

from pathlib import Path

from mocap.recording.sink import NullSink


def make_sink(out_dir: Path, enabled: bool = True, every: int = 1, particles: bool = True,
              images: bool = True, scale: float = 0.25):
    if not enabled:
        return NullSink()
    from mocap.recording.rerun_sink import RerunSink

    return RerunSink(Path(out_dir) / "recording.rrd", every=every, particles=particles,
                     images=images, scale=scale)
