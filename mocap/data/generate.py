"""Plain-object entry point of the dataset generator (the Hydra script only parses config)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.data.corruption import DetectionModel, SilhouetteNoise
from mocap.data.motion import generate_motion
from mocap.data.sequence import Sequence
from mocap.data.source_settings import SyntheticSource
from mocap.data.synthetic import Progress, generate_sequence


def subject_shape(body: BodyModel, seed: int, scale: float) -> np.ndarray:
    """A subject's shape alpha (K,), drawn from its own stream of the seed."""
    return np.random.default_rng([seed, 7]).normal(0.0, scale, body.num_shape)


_S = SyntheticSource         # the defaults (mocap/data/source_settings.py)


def make_synthetic(body: BodyModel, rig: Rig, *, motion: str, frames: int, fps: float, seed: int,
                   split: str = _S.split, shape_scale: float = _S.shape_scale, radius: float = _S.radius,
                   masks: bool = _S.masks, images: bool = _S.images,
                   marker_spheres: bool = _S.marker_spheres, detections: Mapping | None = _S.detections,
                   silhouette_noise: Mapping | None = _S.silhouette_noise, name: str = _S.name,
                   progress: Progress | None = None) -> Sequence:
    """A synthetic sequence rendered for ``rig`` (the settings and their defaults:
    :class:`~mocap.data.source_settings.SyntheticSource`)."""
    chi = generate_motion(body, motion, frames, fps=fps, seed=seed, split=split, radius=radius)
    det = None
    occlusion = True
    if detections and detections.get("enabled", False):
        d = dict(detections)
        d.pop("enabled")
        occlusion = bool(d.pop("occlusion", True))
        det = DetectionModel(**d)
    noise = SilhouetteNoise(**dict(silhouette_noise)) if silhouette_noise else None
    meta = {"generator": "mocap.data.generate.make_synthetic", "motion": motion, "seed": seed,
            "split": split, "shape_scale": shape_scale, "body": body.name,
            "detections": dict(detections or {}), "silhouette_noise": dict(silhouette_noise or {})}
    return generate_sequence(body, rig, chi, subject_shape(body, seed, shape_scale), name=name,
                             fps=fps, seed=seed, masks=masks, images=images,
                             marker_spheres=marker_spheres, detections=det,
                             silhouette_noise=noise, occlusion=occlusion, progress=progress,
                             meta=meta)
