"""Tracker constructors for Hydra (``conf/tracker/*.yaml`` name them in ``_target_``):
plain keyword arguments in, a ready tracker out."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy.prior import ParzenPrior, PosePrior, default_prior_path
from mocap.energy.total import EnergyWeights
from mocap.trackers.apf import APFSettings
from mocap.trackers.apf_tracker import APFTracker


def internal_scale(rig: Rig, resolution: int) -> float:
    """Scale factor that brings the rig's longer image side to ``resolution`` px (<= 1)."""
    if resolution <= 0:
        raise ValueError(f"resolution must be positive, got {resolution}")
    return min(1.0, resolution / float(np.max(rig.sizes)))


def make_pose_prior(body: BodyModel, prior_file: str | None, limit_sigma: float,
                    limit_weight: float, learned_weight: float) -> PosePrior:
    parzen = None
    if learned_weight:
        parzen = ParzenPrior.load(prior_file or default_prior_path(body.name))
    return PosePrior(body.dof_names, body.limits, parzen, limit_sigma=limit_sigma,
                     limit_weight=limit_weight, learned_weight=learned_weight)


def make_apf_tracker(*, body: BodyModel, rig: Rig, rng: np.random.Generator, name: str,
                     particles: int, layers: int, survival: float = 0.5, diffusion: float = 1.0,
                     shrink: float = 0.85, min_std_fraction: float = 0.05, resolution: int = 256,
                     init_std: Sequence[float] = (0.05, 0.05, 0.15), prediction_damping: float = 0.5,
                     energy: Mapping | None = None, prior: Mapping | None = None,
                     keep_particles: bool = False, estimate: str = "mean") -> APFTracker:
    weights = EnergyWeights(**dict(energy or {}))
    pose_prior = None
    if weights.prior:
        pose_prior = make_pose_prior(body, **dict(prior or {}))
    settings = APFSettings(particles=particles, layers=layers, survival=survival,
                           diffusion=diffusion, shrink=shrink, min_std_fraction=min_std_fraction,
                           estimate=estimate)
    return APFTracker(body, rig, settings, weights, rng, prior=pose_prior,
                      scale=internal_scale(rig, resolution),
                      init_std=tuple(init_std), prediction_damping=prediction_damping,
                      keep_particles=keep_particles, name=name)
