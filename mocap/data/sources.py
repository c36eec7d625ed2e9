"""Sequences from configuration (``conf/data/*.yaml``): synthetic in memory, or a folder."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from mocap.body.model import BodyModel
from mocap.cameras import rig_from_config
from mocap.data.generate import make_synthetic
from mocap.data.sequence import Sequence
from mocap.data.sequence_io import load_sequence


def synthetic_sequence(*, body: BodyModel, cameras: str | Mapping, motion: str, frames: int,
                       fps: float, seed: int, name: str = "synthetic", **options) -> Sequence:
    """Generate a sequence in memory (see :func:`mocap.data.generate.make_synthetic`)."""
    rig = rig_from_config(cameras)
    return make_synthetic(body, rig, motion=motion, frames=frames, fps=fps, seed=seed, name=name,
                          **options)


def folder_sequence(*, body: BodyModel, path: str, images: bool = True, name: str | None = None) -> Sequence:
    """A sequence folder written by ``experiments/make_dataset.py`` (or converted data)."""
    p = Path(path)
    if not p.is_dir():
        raise FileNotFoundError(f"data path not found: {p}")
    return load_sequence(p, images=images)
