"""The recording settings (``recording.*``), checked before any work; the sink they describe
is :func:`mocap.recording.factory.make_sink`.

``recording.level`` says what a recording holds (the full list: :mod:`mocap.recording.rerun_sink`):

    summary    per-frame scalars (energies, error, timings, pose chi, decisions), the decision
               log, the run's config / metadata / metrics, the cameras, and the body (mesh and
               skeletons) of the last tracked frame only
    standard   (default) + per recorded frame: the estimated mesh (vertex positions), skeletons,
               3D landmarks; the 2D views at ``scale`` (silhouette difference, detections,
               reprojected landmarks, the input images JPEG-encoded); the annealing layers'
               scalars
    full       + the particles of every annealing layer, and the 2D views and images at full size

The other options refine the level; left at null they take the level's value (:data:`LEVELS`
is their one source): ``every`` (views and meshes every k-th frame), ``particles`` (false,
true: first and last layer, or ``all`` layers), ``images`` (log the input images), ``scale``
(size of the 2D views relative to the camera images, in (0, 1]).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class RecordingSettings:
    """What a recording holds; the defaults are the standard level's. level: summary |
    standard | full; every: views and meshes every k-th frame; particles: False | True
    (first and last layer) | "all" (every layer); images: log the input images; scale: 2D
    views relative to the camera images."""

    enabled: bool = True
    level: str = "standard"
    every: int = 1
    particles: bool | str = False
    images: bool = True
    scale: float = 0.25

    @property
    def per_frame_body(self) -> bool:
        """The mesh, skeletons and 3D landmarks on every recorded frame (not only the last)."""
        return self.level != "summary"

    @property
    def views(self) -> bool:
        """The 2D views (silhouette difference, detections, reprojections, images)."""
        return self.level != "summary"

    @property
    def layers(self) -> bool:
        """The annealing layers' scalars (timeline ``anneal_step``)."""
        return self.level != "summary"

    @property
    def keep_particles(self) -> bool:
        """Whether the tracker must keep its layers' particles for the recording."""
        return bool(self.enabled and self.particles)


#: each level's defaults of the options left at null (the one source of these defaults: the
#: dataclass's are the standard level's, the others say where they differ)
LEVELS: dict[str, RecordingSettings] = {
    "summary": RecordingSettings(level="summary", images=False),
    "standard": RecordingSettings(),
    "full": RecordingSettings(level="full", particles="all", scale=1.0),
}
OPTIONS = ("enabled", "level", "every", "particles", "images", "scale")


def _is_int(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def recording_settings(config: Mapping | None) -> RecordingSettings:
    """The ``recording`` node of a run's config (plain values) as settings; every value is
    checked (also when recording is off), each error names the setting, its value and what
    is allowed."""
    cfg = dict(config or {})
    unknown = sorted(set(cfg) - set(OPTIONS))
    if unknown:
        raise ValueError(f"unknown setting recording.{unknown[0]} (recording options: {', '.join(OPTIONS)})")
    level = cfg.get("level") or "standard"
    if level not in LEVELS:
        raise ValueError(f"setting recording.level = {level!r} is not allowed (one of {', '.join(LEVELS)})")
    s = LEVELS[level]
    enabled = cfg.get("enabled", True)
    if not isinstance(enabled, bool):
        raise ValueError(f"setting recording.enabled = {enabled!r} is not allowed (true or false)")
    every = cfg.get("every")
    if every is not None and (not _is_int(every) or every < 1):
        raise ValueError(f"setting recording.every = {every!r} is not allowed (an integer >= 1, or null: "
                         f"every frame)")
    particles = cfg.get("particles")
    if particles is not None and particles not in (True, False, "all"):
        raise ValueError(f"setting recording.particles = {particles!r} is not allowed (true, false, all, "
                         "or null: the level's)")
    images = cfg.get("images")
    if images is not None and not isinstance(images, bool):
        raise ValueError(f"setting recording.images = {images!r} is not allowed (true, false, or null: "
                         "the level's)")
    scale = cfg.get("scale")
    if scale is not None and (isinstance(scale, bool) or not isinstance(scale, (int, float, np.number))
                              or not 0 < scale <= 1):
        raise ValueError(f"setting recording.scale = {scale!r} is not allowed (a number in (0, 1], or null: "
                         "the level's)")
    return replace(s, enabled=enabled,
                   every=s.every if every is None else int(every),
                   particles=s.particles if particles is None else particles,
                   images=s.images if images is None else images,
                   scale=s.scale if scale is None else float(scale))
