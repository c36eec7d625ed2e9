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
from mocap.trackers.hybrid_tracker import HybridTracker
from mocap.trackers.local_tracker import LocalTracker


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
                     keep_particles: bool = False, estimate: str = "mean",
                     initialization: Mapping | None = None) -> APFTracker:
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
                      keep_particles=keep_particles, name=name, initialization=initialization)


def make_marker_tracker(*, body: BodyModel, rig: Rig, rng: np.random.Generator, name: str,
                        particles: int, layers: int, survival: float = 0.25, diffusion: float = 0.7,
                        shrink: float = 0.85, min_std_fraction: float = 0.05, estimate: str = "mean",
                        gate: float = 0.04, min_views: int = 3, coherence_radius: float = 0.15,
                        coherence_weight: float = 1.0, landmarks: str | Sequence = "auto",
                        init_std: Sequence[float] = (0.02, 0.03, 0.12), prediction_damping: float = 1.0,
                        min_confidence: float = 0.0, init: Mapping | None = None, crossover: bool = True,
                        keep_particles: bool = False, refine: Mapping | None = None,
                        offsets: Mapping | None = None):
    """The marker tracker of Canton-Ferrer et al. 2010 (``conf/tracker/marker_apf.yaml``).
    gate: the outlier threshold tau as a fraction of the image diagonal."""
    from mocap.energy.markers import MarkerLikelihood
    from mocap.trackers.marker_apf import MarkerAPFTracker, make_init, make_offsets, make_refinement

    settings = APFSettings(particles=particles, layers=layers, survival=survival, diffusion=diffusion,
                           shrink=shrink, min_std_fraction=min_std_fraction, estimate=estimate)
    diagonal = float(np.hypot(*np.asarray(rig.sizes, np.float64).mean(axis=0)))
    likelihood = MarkerLikelihood(gate_px=gate * diagonal, min_views=min_views,
                                  coherence_radius=coherence_radius, coherence_weight=coherence_weight)
    if not isinstance(landmarks, str):
        landmarks = [x if isinstance(x, str) else dict(x) for x in landmarks]
    return MarkerAPFTracker(body, rig, settings, likelihood, rng, landmarks=landmarks,
                            init_std=tuple(init_std), prediction_damping=prediction_damping,
                            min_confidence=min_confidence, init=make_init(init), crossover=crossover,
                            keep_particles=keep_particles, name=name, refine=make_refinement(refine),
                            offsets=make_offsets(offsets))


def make_local_tracker(*, body: BodyModel, rig: Rig, rng: np.random.Generator, name: str = "local",
                       keep_particles: bool = False, **options) -> LocalTracker:
    """The local tracker (rng and keep_particles are accepted for a uniform interface)."""
    return LocalTracker(body, rig, name=name, rng=rng, **options)


def make_hybrid_tracker(*, body: BodyModel, rig: Rig, rng: np.random.Generator, name: str = "hybrid",
                        keep_particles: bool = False, apf: Mapping, local: Mapping,
                        initialization: Mapping | None = None) -> HybridTracker:
    a = dict(apf)
    weights = EnergyWeights(**dict(a.pop("energy", {}) or {}))
    prior_cfg = a.pop("prior", None)
    pose_prior = make_pose_prior(body, **dict(prior_cfg or {})) if weights.prior else None
    resolution = a.pop("resolution", 256)
    init_std = tuple(a.pop("init_std", (0.03, 0.03, 0.25)))
    refine = a.pop("refine_iterations", 3)
    settings = APFSettings(**a)
    return HybridTracker(body, rig, rng, settings, weights, pose_prior, internal_scale(rig, resolution),
                         init_std=init_std, refine_iterations=refine, keep_particles=keep_particles,
                         name=name, initialization=initialization, **dict(local))
