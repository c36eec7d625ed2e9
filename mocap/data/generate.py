"""Plain-object entry point of the dataset generator (the Hydra script only parses config)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.data.corruption import DetectionModel, SilhouetteNoise
from mocap.data.motion import generate_motion
from mocap.data.sequence import Sequence
from mocap.data.synthetic import Progress, generate_sequence


def subject_shape(body: BodyModel, seed: int, scale: float) -> np.ndarray:
    """A subject's shape alpha (K,), drawn from its own stream of the seed."""
    return np.random.default_rng([seed, 7]).normal(0.0, scale, body.num_shape)


def make_synthetic(body: BodyModel, rig: Rig, *, motion: str, frames: int, fps: float, seed: int,
                   split: str = "test", shape_scale: float = 0.8, radius: float = 1.0,
                   masks: bool = True, images: bool = False, marker_spheres: bool = False,
                   detections: Mapping | None = None, silhouette_noise: Mapping | None = None,
                   name: str = "synthetic", progress: Progress | None = None) -> Sequence:
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
