"""The silhouette trackers' settings: one frozen dataclass per tracker, the only place their
defaults are written (``local``: :class:`LocalSettings`; ``apf``, ``apf_25x10``,
``apf_prior``: :class:`APFTrackerSettings`; ``hybrid``: :class:`HybridSettings`; the marker
tracker's are in :mod:`mocap.trackers.markers.settings`).

Nested settings are the settings of the trackers' parts, written here too: the annealing
search (:class:`APFSettings`, whose fields the search settings inherit, so that
``particles`` stays a top-level key), the silhouette initialisation (:class:`InitSettings`),
the shape refinement (:class:`ShapeRefinement`), the keypoint cue (:class:`KeypointSettings`)
and the offset learning (:class:`OffsetLearning`); the energy weights
(:mod:`mocap.energy.weights`) and the local optimiser's parts (:mod:`mocap.local.settings`)
are those packages'. This module imports no implementation: the parts import their settings
from here. Build any of them from a mapping with
:func:`~mocap.settings.settings_from_mapping`; the presets are in
:mod:`mocap.trackers.presets`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from mocap.energy.weights import EnergyWeights
from mocap.local.settings import ContourSettings, MisalignmentSettings, SiftSettings
from mocap.settings import check, fields_of

#: the silhouette APFs' energy mesh (apf, apf_prior, the hybrid's APF; :mod:`mocap.body.energy_mesh`):
#: the 10,000-triangle body decimated to 2,000 (1,002 vertices; within 11 mm of the body, 1.9 mm
#: on average). Measured on the model-mismatch benchmark (3 seeds, README): no accuracy lost
#: (apf_prior, hybrid), the APF trackers about 2x faster per frame.
ENERGY_MESH_FACES = 2000

#: the limb chains the hybrid's patrol may search (``HybridSearchSettings.patrol_chains``): every
#: chain, or those rooted at the shoulders (arms) or at the hips (legs)
PATROL_CHAINS = ("all", "arms", "legs")


@dataclass(frozen=True)
class APFSettings:
    particles: int = 100
    layers: int = 15
    survival: float = 0.5          # target survival rate alpha
    diffusion: float = 0.7         # diffusion std = diffusion * spread of the resampled set
    shrink: float = 0.9            # ... times shrink^m in layer m
    min_std_fraction: float = 0.05  # floor: this fraction of the initial std (times shrink^m)
    estimate: str = "mean"          # "mean": weighted mean of the last layer; "best": the
                                    # lowest-energy particle seen in any layer

    def __post_init__(self) -> None:
        check(self, "particles", self.particles >= 2, "an integer >= 2")
        check(self, "layers", self.layers >= 1, "an integer >= 1")
        check(self, "survival", 0.0 < self.survival < 1.0, "(0, 1)")
        check(self, "diffusion", self.diffusion > 0.0, "> 0")
        check(self, "shrink", 0.0 < self.shrink <= 1.0, "(0, 1]")
        check(self, "min_std_fraction", self.min_std_fraction >= 0.0, ">= 0")
        check(self, "estimate", self.estimate in ("mean", "best"), "'mean' or 'best'")


#: a kept hypothesis whose fine E_S is more than this (relative) above the best one's after a
#: round is dropped (InitSettings.prune_margin); the measurements behind it are in
#: docs/results/speed.md
PRUNE_MARGIN = 0.25


@dataclass(frozen=True)
class InitSettings:
    resolution: int = 256
    headings: int = 12
    rounds: int = 2
    pose_particles: int = 60
    pose_layers: int = 10
    shape_particles: int = 40
    shape_layers: int = 8
    shape_components: int = 8
    local_iterations: int = 10
    hypotheses: int = 2           # distinct headings refined (each also at +180 deg, and with
                                  # its limbs swapped); 0: one hypothesis, the best heading only
    keep: int = 2                 # hypotheses taken through the shape/pose rounds
    select_resolution: int = 512  # E_S resolution that ranks hypotheses (px, longest side)
    partitioned: bool = True      # pose search torso first, then limb by limb, then all DOFs
    shape_translate: float = 0.2  # the shape search also shifts the body by up to this (m); 0: off
    energy_mesh: int | None = ENERGY_MESH_FACES  # pose searches' E_S mesh (triangles); None: full mesh
    prune_margin: float | None = PRUNE_MARGIN  # drop a kept hypothesis this far (relative fine
                                  # E_S) behind the best after a round; None: never
    limb_hypotheses: int = 0      # per kept hypothesis, each limb's angles drawn anew this many
                                  # times (the hybrid: from its motion library) before the rounds;
                                  # the limb_keep best (search E_S) searched over the limb's DOFs
                                  # (limb_particles x limb_layers), kept where the fine E_S falls; 0: off
    limb_stage: str = "end"       # "end": the winner's limbs, after the rounds (chosen on dev);
                                  # "start": the kept hypotheses', before the rounds
    limb_keep: int = 3
    limb_particles: int = 30
    limb_layers: int = 6
    search: str = "anneal"        # "anneal": the annealed searches above (INITIALIZER_VERSION 3);
                                  # "retrieval": library poses x headings scored in one batch, the
                                  # best refined without annealing (mocap.trackers.init_retrieval;
                                  # tried on dev, not chosen: docs/results/speed.md)
    retrieval_resolution: int = 128   # px (longest side) of the retrieval and its refinement
    retrieval_headings: int = 12  # headings about the vertical each library pose is tried at
    retrieval_keep: int = 4       # retrieved headings (more than 60 deg apart) searched
    retrieval_samples: int = 40   # proposals per partition and sweep of the coordinate search
    retrieval_sweeps: int = 3     # sweeps of the coordinate search on the keep best candidates
    retrieval_draws: int = 100    # uniform draws of each limb's angles beside the library's (first sweep)
    coarse_layers: int = 0        # the first this many layers of every pose search (the hypotheses'
                                  # and the rounds') scored by a cheaper E_S: at coarse_resolution px
                                  # on a coarse_mesh-triangle mesh; the last layers by the search's own
                                  # (version 6, issue 38); 0: off (version 3: every layer the same)
    coarse_resolution: int = 128  # px (longest side) of the early layers' E_S
    coarse_mesh: int = 500        # triangles of the early layers' mesh (mocap.body.energy_mesh)
    coarse_shape_layers: int = 0  # the first this many layers of every shape search scored at
                                  # coarse_resolution px on the coarse_mesh; 0: off (version 3)
    coarse_energy: str = "raster"  # the early layers' E_S: "raster" (the compiled E_S, coarser);
                                  # "points" (mocap.energy.point_chamfer, the coarse_mesh's vertices
                                  # against the search's own masks, no raster; tried on dev as
                                  # version 7, not chosen: docs/results/speed.md)
    coarse_samples: int = 48      # "points": observed contour samples and pixel samples per view, each
    shape_pose_searches: int = 0  # after everything, this many annealed searches over the pose and the
                                  # first shape_components coefficients together, each kept where the
                                  # fine E_S falls (:mod:`mocap.trackers.start_shape`); 0: off
    shape_pose_particles: int = 100
    shape_pose_layers: int = 10
    shape_pose_pose_scale: float = 0.0   # the pose's own first-layer spread, times the start's pose
                                         # spread (0: the pose only follows the shape)
    shape_pose_shape_std: float = 0.5    # first-layer shape spread (standardised PCA units)

    def __post_init__(self):
        check(self, "energy_mesh", self.energy_mesh is None or self.energy_mesh >= 4,
              "null (the full mesh) or >= 4 triangles")
        check(self, "prune_margin", self.prune_margin is None or self.prune_margin >= 0,
              "null (never) or >= 0 (relative)")
        check(self, "limb_hypotheses", self.limb_hypotheses >= 0, "an integer >= 0 (0: off)")
        for name in ("limb_keep", "limb_layers"):
            check(self, name, getattr(self, name) >= 1, "an integer >= 1")
        check(self, "limb_particles", self.limb_particles >= 2, "an integer >= 2")
        check(self, "limb_stage", self.limb_stage in ("start", "end"), "'start' or 'end'")
        check(self, "search", self.search in ("anneal", "retrieval"), "'anneal' or 'retrieval'")
        for name in ("retrieval_resolution", "retrieval_headings", "retrieval_keep", "retrieval_sweeps"):
            check(self, name, getattr(self, name) >= 1, "an integer >= 1")
        check(self, "retrieval_samples", self.retrieval_samples >= 1, "an integer >= 1")
        check(self, "retrieval_draws", self.retrieval_draws >= 0, "an integer >= 0")
        check(self, "coarse_layers", 0 <= self.coarse_layers < self.pose_layers,
              f"an integer in [0, pose_layers = {self.pose_layers}) (0: off)")
        check(self, "coarse_shape_layers", 0 <= self.coarse_shape_layers < self.shape_layers,
              f"an integer in [0, shape_layers = {self.shape_layers}) (0: off)")
        check(self, "coarse_resolution", self.coarse_resolution >= 16, "an integer >= 16 (px)")
        check(self, "coarse_mesh", self.coarse_mesh >= 4, "an integer >= 4 (triangles)")
        check(self, "coarse_energy", self.coarse_energy in ("raster", "points"), "'raster' or 'points'")
        check(self, "coarse_samples", self.coarse_samples >= 1, "an integer >= 1")
        check(self, "shape_pose_searches", self.shape_pose_searches >= 0, "an integer >= 0 (0: off)")
        check(self, "shape_pose_particles", self.shape_pose_particles >= 2, "an integer >= 2")
        check(self, "shape_pose_layers", self.shape_pose_layers >= 1, "an integer >= 1")
        check(self, "shape_pose_pose_scale", self.shape_pose_pose_scale >= 0, ">= 0")
        check(self, "shape_pose_shape_std", self.shape_pose_shape_std > 0, "> 0")


@dataclass(frozen=True)
class ShapeRefinement:
    """Shape refinement while tracking. ``every``: frames between refinements (0: off);
    the last ``keyframes`` frames, one every ``stride`` frames, are scored; ``components``:
    shape coefficients searched; an annealed search of ``particles`` x ``layers`` with a
    first-layer spread ``std`` (PCA units) per coefficient and ``shift`` (m) on the shared
    3D offset, on silhouettes at ``resolution`` px (longest image side); the result is kept
    when it lowers the keyframes' E_S at ``check_resolution`` px by more than ``min_gain``
    (relative)."""

    every: int = 0
    keyframes: int = 6
    stride: int = 3
    components: int = 8
    particles: int = 30
    layers: int = 6
    std: float = 0.3
    shift: float = 0.02
    resolution: int = 256
    check_resolution: int = 512
    min_gain: float = 0.01

    def __post_init__(self):
        check(self, "every", self.every >= 0, "an integer >= 0 frames (0: off)")
        for name in ("keyframes", "stride", "components", "layers", "resolution", "check_resolution"):
            check(self, name, getattr(self, name) >= 1, "an integer >= 1")
        check(self, "particles", self.particles >= 2, "an integer >= 2")
        check(self, "std", self.std > 0, "> 0")
        check(self, "shift", self.shift >= 0, ">= 0 m")


@dataclass(frozen=True)
class OffsetLearning:
    """frames: tracked frames to learn from (0: off); max_norm: metres; min_samples: per
    landmark; significance: keep a landmark's offset only where its median over the frames is
    this many standard errors from zero (the per-frame spread's, all three axes:
    :func:`mocap.trackers.markers.offsets.offset_significance`; 0: every offset kept)."""

    frames: int = 0
    max_norm: float = 0.08
    min_samples: int = 3
    significance: float = 0.0

    def __post_init__(self) -> None:
        check(self, "frames", self.frames >= 0, "an integer >= 0 (0: off)")
        check(self, "max_norm", self.max_norm >= 0, ">= 0 m")
        check(self, "min_samples", self.min_samples >= 1, "an integer >= 1")
        check(self, "significance", self.significance >= 0, ">= 0 standard errors (0: off)")


@dataclass(frozen=True)
class TwoCueShape:
    """The two-cue hybrid's shape fitted once (or every ``every`` frames) over many tracked frames
    to both cues at once (:mod:`mocap.trackers.two_cue_shape`), in place of the 15-frame keypoint
    refit (``shape_frames``) and the silhouette-only refinements (``local.shape``).
    ``frames``: tracked frames before the first fit (0: off); ``every``: frames between later
    fits over everything seen so far (0: once); ``keyframes``: at most this many of the frames
    whose misalignment check flagged nothing (``aligned_only``; off: of every frame, a flagged
    one with its repaired pose), evenly spaced, carry the silhouette term (poses held as
    tracked); ``components``: shape coefficients fitted (the others held);
    ``view_samples``: the independent samples one view's silhouette counts as against one
    frame's bone length (the silhouettes' evidence; each view's energy is divided by its value
    at the current shape, its residual scale; the bone lengths by their spread over frames);
    ``length_floor``: the least per-frame spread (m) a bone length is credited with;
    ``prior``: the weight of the shape model's prior |alpha_1..C|^2 / 2 (1: the model's own);
    ``particles`` x ``layers``: the annealed search over the coefficients and a shared
    ``shift`` (m) of the body, first-layer spread ``std`` (in the keypoints' posterior standard
    deviations: :meth:`~mocap.trackers.two_cue_shape.LengthEvidence.posterior_root`), on silhouettes
    at ``resolution`` px (longest image side), then at most ``polish`` energy evaluations of
    Powell's method from its result (0: none), then ``quadratic`` iterations (0: none) of a trust
    region on a quadratic model of batched samples, first radius ``quadratic_radius`` (the search's
    units; :mod:`mocap.trackers.quadratic_polish`). ``skeleton`` > 0: at each fit, rest-joint
    corrections (the person's skeleton inside the shape's outline) are fitted too, to the
    keypoints of the aligned frames with their poses held (:func:`mocap.body.skeleton.fit_joint_offsets`),
    ``skeleton`` the prior's spread of each offset coordinate (m; 0: off, the shape's own
    skeleton), ``skeleton_noise`` a triangulated keypoint's (m), ``skeleton_refit`` local steps
    (keypoints and silhouettes) re-fitting each of those frames' poses on the new shape first (0:
    the poses as tracked, with the shape before); the hybrid then tracks on the corrected body
    (the rest mesh unchanged)."""

    frames: int = 0
    every: int = 0
    keyframes: int = 8
    aligned_only: bool = True
    components: int = 10
    view_samples: float = 1.0
    prior: float = 1.0
    length_floor: float = 0.005
    particles: int = 40
    layers: int = 8
    std: float = 1.0
    shift: float = 0.02
    resolution: int = 256
    polish: int = 400
    quadratic: int = 0
    quadratic_radius: float = 1.0
    skeleton: float = 0.0
    skeleton_noise: float = 0.015
    skeleton_refit: int = 0

    def __post_init__(self) -> None:
        check(self, "frames", self.frames >= 0, "an integer >= 0 (0: off)")
        check(self, "skeleton", self.skeleton >= 0, ">= 0 m (0: off)")
        check(self, "skeleton_noise", self.skeleton_noise > 0, "> 0 m")
        check(self, "skeleton_refit", self.skeleton_refit >= 0,
              "an integer >= 0 local steps (0: poses as tracked)")
        check(self, "polish", self.polish >= 0, "an integer >= 0 evaluations (0: none)")
        check(self, "quadratic", self.quadratic >= 0, "an integer >= 0 iterations (0: none)")
        check(self, "quadratic_radius", self.quadratic_radius > 0, "> 0 (the search's standard deviations)")
        check(self, "every", self.every >= 0, "an integer >= 0 (0: once)")
        for name in ("keyframes", "components", "layers", "resolution"):
            check(self, name, getattr(self, name) >= 1, "an integer >= 1")
        check(self, "particles", self.particles >= 2, "an integer >= 2")
        check(self, "view_samples", self.view_samples >= 0, ">= 0 (0: the keypoints alone)")
        check(self, "length_floor", self.length_floor > 0, "> 0 m")
        check(self, "prior", self.prior >= 0, ">= 0 (1: the model's prior, 0: none)")
        check(self, "std", self.std > 0, "> 0")
        check(self, "shift", self.shift >= 0, ">= 0 m")

    @property
    def enabled(self) -> bool:
        return self.frames > 0


@dataclass(frozen=True)
class KeypointSettings:
    """The hybrid's keypoint cue (module docstring): ``weight`` of one keypoint correspondence
    against one contour correspondence in the local optimiser (0: the cue is off, today's
    hybrid); ``energy``: the weight of the marker likelihood (in [0, 1]) beside E_S in the APF
    and its acceptance test; ``flag``: a landmark further than this share of the gate from its
    detections (median over views) makes its limb chain misaligned (0: off); ``gate``: the
    outlier gate tau as a fraction of the image diagonal (as the marker tracker's);
    ``use_confidence``, ``min_confidence``, ``landmarks`` (``auto``: every detection label the
    catalogue knows) and the learned ``offsets`` as the marker tracker's; ``init``: refine the
    self-initialisation's pose with the cue (a search of every limb chain, then local steps);
    ``shape_std``: with ``init``, first fit the body shape to the distances between the
    keypoints triangulated in frame 0 that no pose changes (the marker tracker's start-up fit),
    under a normal prior centred on the silhouettes' shape with this standard deviation (in the
    model's standardised units; 0: keep the silhouettes' shape); ``shape_frames``: with
    ``shape_std`` > 0 and N > 1, the shape is fitted again (same prior) when N frames are in,
    to the median of their triangulated bone lengths (one frame's are off by the detections'
    noise, and that error would stay for the whole sequence); ``shape_follow``: with
    ``shape_frames`` > 1, the keypoints of every frame are kept, the N-frame fit's prior is
    centred on the tracker's current shape (the silhouettes' refinements so far) instead of the
    start's, and after every silhouette shape refinement that was kept (``local.shape.every``)
    the shape is fitted again the same way to the median of all frames so far: each cue corrects
    the other while tracking. Silhouettes measure the body's outline, keypoints its bone lengths,
    which the outline hardly constrains. ``two_cue``: one fit of the shape to both cues over many
    frames (:class:`TwoCueShape`; off by default)."""

    weight: float = 0.0
    energy: float = 1.0
    flag: float = 0.5
    gate: float = 0.04
    use_confidence: bool = True
    min_confidence: float = 0.0
    landmarks: str | tuple = "auto"
    offsets: OffsetLearning = OffsetLearning()
    init: bool = True
    shape_std: float = 0.0
    shape_frames: int = 1
    shape_follow: bool = False
    two_cue: TwoCueShape = TwoCueShape()

    def __post_init__(self) -> None:
        check(self, "weight", self.weight >= 0, ">= 0 (0: no keypoint cue)")
        check(self, "energy", self.energy >= 0, ">= 0")
        check(self, "flag", 0.0 <= self.flag <= 1.0, "[0, 1] of the gate (0: off)")
        check(self, "gate", 0.0 < self.gate <= 1.0, "(0, 1], a fraction of the image diagonal")
        check(self, "min_confidence", 0.0 <= self.min_confidence <= 1.0, "[0, 1]")
        check(self, "shape_std", self.shape_std >= 0, ">= 0 (0: the silhouettes' shape)")
        check(self, "shape_frames", self.shape_frames >= 1, "an integer >= 1 (1: frame 0 only)")
        check(self, "landmarks", isinstance(self.landmarks, str | tuple),
              "a landmark set's name (auto) or a list of landmark names / entries")

    @property
    def enabled(self) -> bool:
        return self.weight > 0


#: the first-layer diffusion std: (twist v (m), twist omega (rad), joint angles (rad))
Std3 = tuple[float, float, float]


@dataclass(frozen=True)
class PriorSettings:
    """The pose prior E_P of Zhang et al. (Eq. 14), :func:`mocap.trackers.factory.make_pose_prior`:
    a joint-limit penalty (``limit_sigma`` rad, weight ``limit_weight``) plus the learned
    Parzen density (weight ``learned_weight``; 0: limits only) read from ``prior_file``, or,
    when that is None, the prior of ``prior_source`` shipped for the body
    (:func:`mocap.energy.prior.prior_path`: ``procedural`` or ``real``)."""

    prior_file: str | None = None
    prior_source: str = "procedural"
    limit_sigma: float = 0.1
    limit_weight: float = 1.0
    learned_weight: float = 1.0

    def __post_init__(self) -> None:
        check(self, "limit_sigma", self.limit_sigma > 0, "> 0 rad")
        check(self, "limit_weight", self.limit_weight >= 0, ">= 0")
        check(self, "learned_weight", self.learned_weight >= 0, ">= 0")


@dataclass(frozen=True)
class SilhouetteSearchSettings(APFSettings):
    """An annealed search on the silhouette energy: the search (:class:`APFSettings`' fields),
    the energy weights, the pose prior, the internal silhouette ``resolution`` (px of the
    longer image side) and ``energy_mesh``: E_S rasterises the body decimated to that many
    triangles (None: the full mesh)."""

    energy: EnergyWeights = EnergyWeights()
    prior: PriorSettings = PriorSettings()
    resolution: int = 256
    energy_mesh: int | None = ENERGY_MESH_FACES

    def __post_init__(self) -> None:
        super().__post_init__()
        check(self, "resolution", self.resolution >= 1, "an integer >= 1 px")
        check(self, "energy_mesh", self.energy_mesh is None or self.energy_mesh >= 4, "null or >= 4 faces")

    @property
    def search(self) -> APFSettings:
        """The annealing search alone."""
        return APFSettings(**fields_of(self, APFSettings))


def _check_std(settings, name: str = "init_std") -> None:
    std = getattr(settings, name)
    check(settings, name, len(std) == 3 and all(float(v) >= 0 for v in std),
          "3 numbers >= 0: twist v (m), twist omega (rad), joint angles (rad)")


@dataclass(frozen=True)
class APFTrackerSettings(SilhouetteSearchSettings):
    """``apf`` (Zhang et al. 2013, Sec. 4.2; ``apf_prior`` and ``apf_25x10`` are presets of it):
    the search, its first-layer diffusion ``init_std``, the constant-velocity prediction
    chi_t + d (chi_t - chi_{t-1}) (``prediction_damping`` d), the self-initialisation's
    settings, and ``keep_particles`` (keep every layer's particles in the diagnostics)."""

    init_std: Std3 = (0.03, 0.03, 0.08)
    prediction_damping: float = 1.0
    initialization: InitSettings = InitSettings()
    keep_particles: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_std(self)
        check(self, "prediction_damping", 0.0 <= self.prediction_damping <= 1.0, "[0, 1]")


@dataclass(frozen=True)
class TrackSmoothing:
    """``smoothing``: the finished track's zero-phase Butterworth low-pass
    (:mod:`mocap.trackers.smoothing`; the recording, motion.npz and metrics all hold the smoothed
    track). ``cutoff_hz``: its cut-off (Hz, at the sequence's frame rate; 0: off, the track as
    tracked); ``order``: the filter's order (the forward-backward pass doubles it)."""

    cutoff_hz: float = 0.0
    order: int = 4

    def __post_init__(self) -> None:
        number = isinstance(self.cutoff_hz, int | float) and not isinstance(self.cutoff_hz, bool)
        check(self, "cutoff_hz", number and math.isfinite(self.cutoff_hz) and self.cutoff_hz >= 0,
              "a number >= 0 (0: off)")
        integer = isinstance(self.order, int) and not isinstance(self.order, bool)
        check(self, "order", integer and 1 <= self.order <= 8, "an integer in [1, 8]")

    @property
    def enabled(self) -> bool:
        return self.cutoff_hz > 0


@dataclass(frozen=True)
class LocalStepSettings:
    """Local optimisation (Zhang et al. 2013, Sec. 4.1): at most ``iterations`` linearised
    steps with Levenberg ``damping``, stopping when the pose moves less than ``tolerance`` or
    (``energy_tolerance`` > 0) when an iteration lowered the RMS point-line distance by less
    than that share; the contour and SIFT correspondences, the misalignment check and the
    shape refinement (``shape.every``: frames between refinements, 0: off). ``active_limits``:
    each linearised step is solved within the joint limits (an angle at its limit held there
    while the others take up what it cannot give: :func:`mocap.local.solver.bounded_solve`)
    instead of solved free and clipped after (off: the paper's step)."""

    iterations: int = 10
    tolerance: float = 1e-4
    damping: float = 1e-3
    prediction_damping: float = 1.0
    energy_tolerance: float = 0.0
    active_limits: bool = False
    contour: ContourSettings = field(default_factory=ContourSettings)
    sift: SiftSettings = field(default_factory=SiftSettings)
    misalignment: MisalignmentSettings = field(default_factory=MisalignmentSettings)
    shape: ShapeRefinement = ShapeRefinement()

    def __post_init__(self) -> None:
        check(self, "iterations", self.iterations >= 0, "an integer >= 0")
        check(self, "tolerance", self.tolerance >= 0, ">= 0")
        check(self, "damping", self.damping >= 0, ">= 0")
        check(self, "prediction_damping", 0.0 <= self.prediction_damping <= 1.0, "[0, 1]")
        check(self, "energy_tolerance", 0.0 <= self.energy_tolerance < 1.0, "[0, 1)")


@dataclass(frozen=True)
class LocalSettings(LocalStepSettings):
    """``local``: the local step, the self-initialisation's settings, the finished track's
    ``smoothing`` (off by default); ``keep_particles`` is accepted for a uniform interface (the
    local tracker has none)."""

    initialization: InitSettings = InitSettings()
    keep_particles: bool = False
    smoothing: TrackSmoothing = TrackSmoothing()


@dataclass(frozen=True)
class HybridSearchSettings(SilhouetteSearchSettings):
    """The hybrid's APF over the misaligned limbs: a small budget, without the pose prior (ours is
    learned from our own motion library and pulls limbs away on motions from other code), its
    first layer wide (``init_std``: the search starts from a limb known to be wrong) with a
    share ``restart`` of it drawn uniformly within the searched angles' limits, of which a share
    ``restart_from_library`` take a pose of the pose prior's training motions (mirrored or not);
    ``refine_iterations`` local iterations follow. ``patrol`` = N: every N-th frame with nothing
    flagged one limb chain in turn is searched all the same (0: off), its pose kept only where
    E_S falls by more than ``patrol_margin`` and in a share ``patrol_agreement`` of the views;
    ``patrol_chains``: which chains it searches, ``all``, ``arms`` (the chains rooted at the
    shoulders: a forearm held in front of the torso stays inside the silhouettes, where the
    check cannot see it) or ``legs`` (rooted at the hips). ``heading_chains`` = N: where the
    check flags at least N limb chains at once, the repair first turns the local step's pose
    about the vertical through its pelvis by each of ``heading_angles`` (degrees), runs the
    local step from each, and the limb search starts from whichever of them and the unturned
    pose has the lowest E_S (0: off; a turn the local step did not follow leaves every limb off
    the silhouettes, and the limbs' angles cannot turn the torso:
    :mod:`mocap.trackers.heading`). ``stuck_frames`` = N: where a limb chain has been flagged on
    N frames in a row, the repair's search has ``stuck_particles`` particles and three quarters
    of its first layer take the flagged chains' angles from the motion library (0: off; a limb
    wrong from the start is flagged frame after frame while the usual search, a few library
    draws among 25 particles, never finds it)."""

    particles: int = 25
    layers: int = 10
    init_std: Std3 = (0.03, 0.03, 0.25)
    refine_iterations: int = 3
    restart: float = 0.5
    restart_from_library: float = 0.5
    patrol: int = 0
    patrol_agreement: float = 0.0
    patrol_margin: float = 0.0
    patrol_chains: str = "all"
    heading_chains: int = 0
    heading_angles: tuple[float, ...] = (-30.0, -15.0, 15.0, 30.0)
    stuck_frames: int = 0
    stuck_particles: int = 100

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_std(self)
        check(self, "refine_iterations", self.refine_iterations >= 0, "an integer >= 0")
        check(self, "restart", 0.0 <= self.restart <= 1.0, "[0, 1]")
        check(self, "restart_from_library", 0.0 <= self.restart_from_library <= 1.0, "[0, 1]")
        check(self, "patrol", self.patrol >= 0, "an integer >= 0 frames")
        check(self, "patrol_agreement", 0.0 <= self.patrol_agreement <= 1.0, "[0, 1]")
        check(self, "patrol_margin", 0.0 <= self.patrol_margin < 1.0, "[0, 1)")
        check(self, "patrol_chains", self.patrol_chains in PATROL_CHAINS,
              "one of " + ", ".join(PATROL_CHAINS))
        check(self, "heading_chains", self.heading_chains >= 0, "an integer >= 0 chains (0: off)")
        check(self, "stuck_frames", self.stuck_frames >= 0, "an integer >= 0 frames (0: off)")
        check(self, "stuck_particles", self.stuck_particles >= 2, "an integer >= 2")
        angles = self.heading_angles
        check(self, "heading_angles", isinstance(angles, tuple) and len(angles) >= 1
              and all(isinstance(a, int | float) and math.isfinite(a) and abs(a) <= 180 for a in angles),
              "a list of at least one angle in [-180, 180] degrees")


@dataclass(frozen=True)
class StartOverFrames:
    """The silhouette-only hybrid's start chosen over several frames
    (:mod:`mocap.trackers.start_frames`): with ``frames`` = N > 0, the self-initialisation's pose
    and its ambiguous alternatives (arms exchanged, legs exchanged, all limbs exchanged, turned 180
    degrees, turned with all limbs exchanged; the start turned by each of ``turns``, degrees
    about the vertical; and ``restarts`` more self-initialisations of frame 0 from other random
    states, each with its own shape) are each tracked over frames 0..N by the local step
    alone, and the one of lowest silhouette energy summed over those frames, where it is lower than
    the start's by more than the share ``margin``, replaces the start: frames 0..N are tracked
    again from it (the run's track revised; a run of N frames or fewer keeps its start). 0: off (the
    start as the initialiser gives it)."""

    frames: int = 0
    margin: float = 0.0
    turns: tuple[float, ...] = ()
    restarts: int = 0

    def __post_init__(self) -> None:
        check(self, "frames", isinstance(self.frames, int) and 0 <= self.frames <= 30,
              "an integer in [0, 30] frames (0: off)")
        check(self, "margin", 0.0 <= self.margin < 1.0, "[0, 1)")
        check(self, "turns", isinstance(self.turns, tuple) and all(
              isinstance(a, int | float) and math.isfinite(a) and 0 < abs(a) < 360 for a in self.turns),
              "a list of angles in (-360, 360) degrees, none 0")
        check(self, "restarts", isinstance(self.restarts, int) and 0 <= self.restarts <= 8,
              "an integer in [0, 8]")


#: the silhouette-only hybrid's local step solved within the joint limits (``active_limits``), chosen on
#: the real-motion dev split together with HYBRID_STUCK_FRAMES (issue 34 item 4: docs/results/surface.md,
#: "Silhouette-only hybrid: repair and start over frames"); ``hybrid_kp`` had it already
HYBRID_ACTIVE_LIMITS = True
#: ... and its repair's wide search for a limb chain flagged this many frames in a row
#: (HybridSearchSettings.stuck_frames; ``hybrid_kp`` keeps it off: not measured with keypoints)
HYBRID_STUCK_FRAMES = 3
#: ... and its patrol: every frame on which the check flags nothing, one arm in turn is searched by the
#: repair all the same, its pose kept where E_S falls by 1 % and in 3 of 4 views (a forearm held in front
#: of the torso stays inside the silhouettes, where the check cannot see it); chosen on the real-motion dev
#: split, seeds 0-2 (issue 34 item 4: docs/results/surface.md, "Silhouette-only hybrid: the patrol over
#: three seeds"); off in HybridSearchSettings and for ``hybrid_kp`` (not measured with keypoints)
HYBRID_PATROL = 1
HYBRID_PATROL_CHAINS = "arms"
HYBRID_PATROL_AGREEMENT = 0.75
HYBRID_PATROL_MARGIN = 0.01


def _hybrid_local() -> LocalStepSettings:
    """The hybrid's local step: the misalignment check also charges observed pixels the model
    leaves unexplained to the nearest limb chain (0: the paper's one-sided check), the shape is
    refined while tracking, and each step is solved within the joint limits."""
    return LocalStepSettings(misalignment=MisalignmentSettings(unexplained=0.005),
                             shape=ShapeRefinement(every=10), active_limits=HYBRID_ACTIVE_LIMITS)


def _hybrid_apf() -> HybridSearchSettings:
    """The hybrid's repair search: a limb chain flagged HYBRID_STUCK_FRAMES frames in a row gets the
    wide search; the arms are patrolled (HYBRID_PATROL...)."""
    return HybridSearchSettings(stuck_frames=HYBRID_STUCK_FRAMES, patrol=HYBRID_PATROL,
                                patrol_chains=HYBRID_PATROL_CHAINS, patrol_agreement=HYBRID_PATROL_AGREEMENT,
                                patrol_margin=HYBRID_PATROL_MARGIN)


#: the silhouette-only hybrid's start: the self-initialisation's winner with each limb searched anew
#: (200 draws from the motion library, InitSettings.limb_stage "end"), chosen on the real-motion dev
#: split (issue 34 item 4: docs/results/surface.md, "Silhouette-only hybrid: the start")
HYBRID_LIMB_HYPOTHESES = 200
#: ... and then its shape searched with the pose following it (InitSettings.shape_pose_searches), chosen on
#: the real-motion dev split (issue 34 item 4: docs/results/surface.md, "Silhouette-only hybrid: shape with
#: pose at the start")
HYBRID_SHAPE_POSE_SEARCHES = 2


def _hybrid_init() -> InitSettings:
    """The hybrid's self-initialisation: the silhouette start, then the winner's limbs searched anew,
    then its shape with its pose."""
    return InitSettings(limb_hypotheses=HYBRID_LIMB_HYPOTHESES,
                        shape_pose_searches=HYBRID_SHAPE_POSE_SEARCHES)


#: the silhouette-only hybrid's start chosen over frames: its exchanged limbs and turns and one more
#: self-initialisation from another random state, each tracked by the local step over frames 0..5, the lowest
#: summed E_S kept (StartOverFrames), chosen on the real-motion dev split, seeds 0-2 (issue 34 item 4:
#: docs/results/surface.md, "Silhouette-only hybrid: starts scored over frames"); ``hybrid_kp`` keeps it off
HYBRID_START_FRAMES = 5
HYBRID_START_RESTARTS = 1


def _hybrid_start_frames() -> StartOverFrames:
    """The silhouette-only hybrid's start chosen over its first HYBRID_START_FRAMES frames among its
    ambiguous alternatives and HYBRID_START_RESTARTS more self-initialisations."""
    return StartOverFrames(frames=HYBRID_START_FRAMES, restarts=HYBRID_START_RESTARTS)


@dataclass(frozen=True)
class HybridSettings:
    """``hybrid``, the full system of Zhang et al. 2013: the local step every frame
    (``local``), the APF over the misaligned limbs (``apf``), the 2D keypoint cue
    (``keypoints``; its ``weight`` 0: off, the paper's silhouette-only system; ``hybrid_kp``:
    on, :mod:`mocap.trackers.keypoint_cue`), the self-initialisation's settings (the silhouette
    start with the winner's limbs searched anew; ``hybrid_kp`` keeps the plain start, its keypoint
    search refines it) and ``keep_particles``. ``start_search``: without the keypoint cue,
    search every limb chain of the self-initialisation's pose in turn with the limb-repair APF,
    each kept where the frame's E_S falls, then a local step (kept where it falls too): the
    start's limbs get the search a misaligned limb gets while tracking, which the check after
    the start never asks for
    (:meth:`~mocap.trackers.hybrid_tracker.HybridTracker.refine_initial`). ``smoothing``: the
    finished track's zero-phase low-pass (:class:`TrackSmoothing`, off by default).
    ``joint_limits``: the tracker's own joint limits ('': the body's; ``widened``: those widened
    from the training motion, shipped per body; else a JSON file {dof: [lo, hi] degrees}:
    :mod:`mocap.trackers.joint_limits`); the silhouette start and everything outside the tracker
    (oracles, other trackers) keep the body's. ``start_frames``: the silhouette-only start chosen
    among its ambiguous alternatives and more self-initialisations over the first frames
    (:class:`StartOverFrames`; off in that dataclass, on here; without the keypoint cue only)."""

    local: LocalStepSettings = field(default_factory=_hybrid_local)
    apf: HybridSearchSettings = field(default_factory=_hybrid_apf)
    keypoints: KeypointSettings = KeypointSettings()
    initialization: InitSettings = field(default_factory=_hybrid_init)
    keep_particles: bool = False
    start_search: bool = False
    smoothing: TrackSmoothing = TrackSmoothing()
    joint_limits: str = ""
    start_frames: StartOverFrames = field(default_factory=_hybrid_start_frames)
