"""Tracker constructors for Hydra (``conf/tracker/*.yaml`` name them in ``_target_``):
plain keyword arguments in, a ready tracker out."""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy.prior import ParzenPrior, PosePrior, default_prior_path
from mocap.energy.total import EnergyWeights
from mocap.trackers.apf import APFSettings
from mocap.trackers.apf_tracker import APFTracker
from mocap.trackers.hybrid_tracker import HybridTracker, library_poses
from mocap.trackers.local_tracker import LocalTracker


def internal_scale(rig: Rig, resolution: int) -> float:
    """Scale factor that brings the rig's longer image side to ``resolution`` px (<= 1)."""
    if resolution <= 0:
        raise ValueError(f"resolution must be positive, got {resolution}")
    return min(1.0, resolution / float(np.max(rig.sizes)))


def make_pose_prior(body: BodyModel, prior_file: str | None = None, limit_sigma: float = 0.1,
                    limit_weight: float = 1.0, learned_weight: float = 1.0) -> PosePrior:
    """E_P of Zhang et al. (Eq. 14): joint-limit penalty (sigma in rad) + the learned Parzen
    density (``prior_file``; None: the prior shipped for the body)."""
    parzen = None
    if learned_weight:
        parzen = ParzenPrior.load(prior_file or default_prior_path(body.name))
    return PosePrior(body.dof_names, body.limits, parzen, limit_sigma=limit_sigma,
                     limit_weight=limit_weight, learned_weight=learned_weight)


def merge(base: Mapping, overrides: Mapping) -> dict:
    """``base`` updated by ``overrides``, nested mappings merged key by key."""
    out = dict(base)
    for k, v in overrides.items():
        out[k] = merge(out[k], v) if isinstance(v, Mapping) and isinstance(out.get(k), Mapping) else v
    return out


SEARCH_FIELDS = tuple(f.name for f in dataclasses.fields(APFSettings))


def _search(options: dict, **defaults) -> APFSettings:
    """APFSettings from the search keys of ``options`` (popped), over ``defaults``."""
    return APFSettings(**{**defaults, **{k: options.pop(k) for k in list(options) if k in SEARCH_FIELDS}})


def _energy(body: BodyModel, energy: Mapping | None, prior: Mapping | None
            ) -> tuple[EnergyWeights, PosePrior | None]:
    weights = EnergyWeights(**dict(energy or {}))
    return weights, (make_pose_prior(body, **dict(prior or {})) if weights.prior else None)


def make_apf_tracker(*, body: BodyModel, rig: Rig, rng: np.random.Generator, name: str = "apf",
                     resolution: int = 256, energy: Mapping | None = None, prior: Mapping | None = None,
                     **options) -> APFTracker:
    """The silhouette APF. Search keys (particles, layers, survival, diffusion, shrink,
    min_std_fraction, estimate) go to :class:`APFSettings`, energy weights to
    :class:`EnergyWeights`, prior options to :func:`make_pose_prior`, the rest (init_std,
    prediction_damping, keep_particles, initialization, energy_mesh: the silhouette energy
    rasterises the body decimated to that many triangles, default
    :data:`~mocap.body.energy_mesh.ENERGY_MESH_FACES`, None the full mesh) to
    :class:`APFTracker`; every default is theirs. resolution: internal silhouette resolution,
    px of the longer image side."""
    options = dict(options)
    settings = _search(options)
    weights, pose_prior = _energy(body, energy, prior)
    if "init_std" in options:
        options["init_std"] = tuple(options["init_std"])
    return APFTracker(body, rig, settings, weights, rng, prior=pose_prior,
                      scale=internal_scale(rig, resolution), name=name, **options)


def make_marker_tracker(*, body: BodyModel, rig: Rig, rng: np.random.Generator, name: str = "marker_apf",
                        gate: float = 0.04, min_views: int = 3, coherence_radius: float = 0.15,
                        coherence_weight: float = 1.0, use_confidence: bool = False,
                        landmarks: str | Sequence = "auto", init: Mapping | None = None,
                        refine: Mapping | None = None, offsets: Mapping | None = None, **options):
    """The marker tracker of Canton-Ferrer et al. 2010 (``conf/tracker/marker_apf.yaml``).
    gate: the outlier threshold tau as a fraction of the image diagonal; use_confidence: the
    likelihood weighs detections by their confidence. Search keys go to
    :class:`APFSettings` (the marker defaults: 100 x 6, survival 0.25, shrink 0.85), the
    rest (init_std, prediction_damping, min_confidence, crossover, keep_particles) to
    :class:`MarkerAPFTracker`."""
    from mocap.energy.markers import MarkerLikelihood
    from mocap.trackers.markers.tracker import MarkerAPFTracker, make_init, make_offsets, make_refinement

    options = dict(options)
    settings = _search(options, layers=6, survival=0.25, shrink=0.85)
    diagonal = float(np.hypot(*np.asarray(rig.sizes, np.float64).mean(axis=0)))
    likelihood = MarkerLikelihood(gate_px=gate * diagonal, min_views=min_views,
                                  coherence_radius=coherence_radius, coherence_weight=coherence_weight,
                                  use_confidence=use_confidence)
    if not isinstance(landmarks, str):
        landmarks = [x if isinstance(x, str) else dict(x) for x in landmarks]
    if "init_std" in options:
        options["init_std"] = tuple(options["init_std"])
    return MarkerAPFTracker(body, rig, settings, likelihood, rng, landmarks=landmarks,
                            init=make_init(init), refine=make_refinement(refine),
                            offsets=make_offsets(offsets), name=name, **options)


def make_local_tracker(*, body: BodyModel, rig: Rig, rng: np.random.Generator, name: str = "local",
                       keep_particles: bool = False, **options) -> LocalTracker:
    """The local tracker (rng and keep_particles are accepted for a uniform interface)."""
    return LocalTracker(body, rig, name=name, rng=rng, **options)


#: the hybrid's APF: 25 x 10 (``apf_25x10``), with a wide first layer of which half is drawn
#: uniformly within the limits of the searched angles (``restart``). Without the pose prior:
#: Zhang et al.'s hybrid uses it (``energy: {prior: 1.0}``), but ours is learned from our own
#: motion library and on motions from other code it pulls limbs away (README, model-mismatch
#: benchmark: walk 77 -> 63 mm, gesture 42 -> 34 mm, box 42 -> 48 mm; our own data unchanged)
#: ``patrol`` (off): every N-th frame on which nothing is flagged, search one limb chain in turn
#: all the same. With 8 exact views it helps (3 seeds, off -> every 2nd frame -> every frame: box
#: 33.1 -> 28.1 -> 23.2 mm, walk 26.4 -> 26.6 -> 23.8, gesture 22.8 -> 21.6 -> 22.1), but with 4
#: views every frame lost the walk and the gesture (26 and 34 frames lost, seed 0) and with noisy
#: silhouettes every 2nd frame was worse on all three sequences: E_S alone accepts wrong limbs
#: where the silhouettes say less (README)
HYBRID_APF = {"particles": 25, "layers": 10, "energy": {"prior": 0.0}, "init_std": (0.03, 0.03, 0.25),
              "restart": 0.5, "restart_from_library": 0.5, "patrol": 0}
#: the hybrid refines its shape every 10 frames on keyframes whose limbs were all aligned
#: (:class:`mocap.trackers.shape_search.ShapeRefinement`); ``every: 0`` turns it off. With the
#: library restarts, on the model-mismatch benchmark (3 seeds): walk 28.3 -> 26.4 mm, box
#: 35.5 -> 33.1, gesture 24.6 -> 22.8 (README)
HYBRID_SHAPE = {"every": 10}
#: the hybrid's misalignment check also charges unexplained observed pixels to the nearest limb
#: chain (:class:`mocap.local.misalignment.MisalignmentDetector`); ``unexplained: 0`` turns
#: that side off (the paper's one-sided check)
HYBRID_MISALIGNMENT = {"unexplained": 0.005}


def make_hybrid_tracker(*, body: BodyModel, rig: Rig, rng: np.random.Generator, name: str = "hybrid",
                        keep_particles: bool = False, apf: Mapping | None = None,
                        local: Mapping | None = None, initialization: Mapping | None = None) -> HybridTracker:
    """The hybrid tracker: ``local`` holds :class:`LocalTracker`'s options, ``apf`` those of
    its APF (as for :func:`make_apf_tracker`, plus refine_iterations, restart and
    restart_from_library: the share of the restarted particles that take a pose of the pose
    prior's training motions, mirrored or not; patrol: every that many frames with nothing
    flagged, search one limb chain in turn all the same; energy_mesh: as for the APF; default
    :data:`HYBRID_APF`); the local
    tracker's misalignment check defaults to :data:`HYBRID_MISALIGNMENT`, its shape
    refinement to :data:`HYBRID_SHAPE`. ``_target_`` and ``name`` keys of composed configs are
    ignored."""
    a = merge(HYBRID_APF, {k: v for k, v in dict(apf or {}).items() if k not in ("_target_", "name")})
    loc = {k: v for k, v in dict(local or {}).items() if k not in ("_target_", "name", "keep_particles")}
    loc["misalignment"] = merge(HYBRID_MISALIGNMENT, dict(loc.get("misalignment") or {}))
    loc["shape"] = merge(HYBRID_SHAPE, dict(loc.get("shape") or {}))
    prior = dict(a.pop("prior", None) or {})
    weights, pose_prior = _energy(body, a.pop("energy", None), prior)
    scale = internal_scale(rig, a.pop("resolution", 256))
    extra = {k: a.pop(k) for k in ("refine_iterations", "restart", "restart_from_library", "patrol",
                                    "patrol_agreement", "patrol_margin", "energy_mesh") if k in a}
    if extra.get("restart_from_library"):
        # the restarts' motion library: the pose prior's training poses, and their mirror images
        path = prior.get("prior_file") or default_prior_path(body.name)
        if prior.get("prior_file") or Path(path).is_file():
            lib = ParzenPrior.load(path)
            extra["library"] = library_poses(body, lib.samples, lib.dof_names)
        else:
            warnings.warn(f"no pose prior shipped for body {body.name!r} ({path}): the hybrid's restarts "
                          "draw uniformly within the joint limits (apf.prior.prior_file names one)",
                          stacklevel=2)
    init_std = tuple(a.pop("init_std"))
    settings = _search(a)
    if a:
        raise TypeError(f"unknown hybrid apf options: {sorted(a)}")
    return HybridTracker(body, rig, rng, settings, weights, pose_prior, scale, init_std=init_std,
                         keep_particles=keep_particles, name=name, initialization=initialization,
                         **extra, **loc)
