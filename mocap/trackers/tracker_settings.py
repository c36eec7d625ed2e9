"""The silhouette trackers' settings: one frozen dataclass per tracker, the only place their
defaults are written (``local``: :class:`LocalSettings`; ``apf``, ``apf_25x10``,
``apf_prior``: :class:`APFTrackerSettings`; ``hybrid``: :class:`HybridSettings`; the marker
tracker's are in :mod:`mocap.trackers.markers.settings`).

Nested settings reuse the dataclasses of what they configure: the annealing search
(:class:`~mocap.trackers.anneal.APFSettings`, whose fields the search settings inherit, so
that ``particles`` stays a top-level key), the energy weights, the silhouette
initialisation, the shape refinement. The contour matcher, the SIFT tracker and the
misalignment check take keyword arguments; their settings classes are made from those
signatures (:func:`~mocap.settings.signature_settings`), so their defaults stay
written there. Build any of them from a mapping with
:func:`~mocap.settings.settings_from_mapping`; the presets are in
:mod:`mocap.trackers.presets`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mocap.body.energy_mesh import ENERGY_MESH_FACES
from mocap.energy.total import EnergyWeights
from mocap.local.contour import ContourMatcher
from mocap.local.misalignment import MisalignmentDetector
from mocap.local.sift import SiftTracker
from mocap.settings import check, fields_of, signature_settings
from mocap.trackers.anneal import APFSettings
from mocap.trackers.initialization import InitSettings
from mocap.trackers.keypoint_cue import KeypointSettings
from mocap.trackers.shape_search import ShapeRefinement

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


ContourSettings = signature_settings(
    "ContourSettings", ContourMatcher.__init__, skip=("body", "rig"),
    doc="The contour matcher's options (:class:`mocap.local.contour.ContourMatcher`, its defaults).",
    module=__name__)
SiftSettings = signature_settings(
    "SiftSettings", SiftTracker.__init__, skip=("body", "rig"), extra=(("enabled", bool, True),),
    doc="SIFT correspondences (``enabled``) and the options of :class:`mocap.local.sift.SiftTracker`.",
    module=__name__)
MisalignmentSettings = signature_settings(
    "MisalignmentSettings", MisalignmentDetector.__init__, skip=("body", "rig"),
    doc="The misalignment check's options (:class:`mocap.local.misalignment.MisalignmentDetector`).",
    module=__name__)


@dataclass(frozen=True)
class LocalStepSettings:
    """Local optimisation (Zhang et al. 2013, Sec. 4.1): at most ``iterations`` linearised
    steps with Levenberg ``damping``, stopping when the pose moves less than ``tolerance`` or
    (``energy_tolerance`` > 0) when an iteration lowered the RMS point-line distance by less
    than that share; the contour and SIFT correspondences, the misalignment check and the
    shape refinement (``shape.every``: frames between refinements, 0: off)."""

    iterations: int = 10
    tolerance: float = 1e-4
    damping: float = 1e-3
    prediction_damping: float = 1.0
    energy_tolerance: float = 0.0
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
    """``local``: the local step, the self-initialisation's settings; ``keep_particles`` is
    accepted for a uniform interface (the local tracker has none)."""

    initialization: InitSettings = InitSettings()
    keep_particles: bool = False


@dataclass(frozen=True)
class HybridSearchSettings(SilhouetteSearchSettings):
    """The hybrid's APF over the misaligned limbs: a small budget, without the pose prior (ours is
    learned from our own motion library and pulls limbs away on motions from other code),
    its first layer wide (``init_std``: the search starts from a limb known to be wrong) with a
    share ``restart`` of it drawn uniformly within the searched angles' limits, of which a
    share ``restart_from_library`` take a pose of the pose prior's training motions (mirrored
    or not); ``refine_iterations`` local iterations follow. ``patrol`` = N: every N-th frame
    with nothing flagged one limb chain in turn is searched all the same (0: off), its pose kept
    only where E_S falls by more than ``patrol_margin`` and in a share ``patrol_agreement`` of
    the views."""

    particles: int = 25
    layers: int = 10
    init_std: Std3 = (0.03, 0.03, 0.25)
    refine_iterations: int = 3
    restart: float = 0.5
    restart_from_library: float = 0.5
    patrol: int = 0
    patrol_agreement: float = 0.0
    patrol_margin: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_std(self)
        check(self, "refine_iterations", self.refine_iterations >= 0, "an integer >= 0")
        check(self, "restart", 0.0 <= self.restart <= 1.0, "[0, 1]")
        check(self, "restart_from_library", 0.0 <= self.restart_from_library <= 1.0, "[0, 1]")
        check(self, "patrol", self.patrol >= 0, "an integer >= 0 frames")
        check(self, "patrol_agreement", 0.0 <= self.patrol_agreement <= 1.0, "[0, 1]")
        check(self, "patrol_margin", 0.0 <= self.patrol_margin < 1.0, "[0, 1)")


def _hybrid_local() -> LocalStepSettings:
    """The hybrid's local step: the misalignment check also charges observed pixels the model
    leaves unexplained to the nearest limb chain (0: the paper's one-sided check), and the
    shape is refined while tracking."""
    return LocalStepSettings(misalignment=MisalignmentSettings(unexplained=0.005),
                             shape=ShapeRefinement(every=10))


@dataclass(frozen=True)
class HybridSettings:
    """``hybrid``, the full system of Zhang et al. 2013: the local step every frame
    (``local``), the APF over the misaligned limbs (``apf``), the 2D keypoint cue
    (``keypoints``; its ``weight`` 0: off, the paper's silhouette-only system; ``hybrid_kp``:
    on, :mod:`mocap.trackers.keypoint_cue`), the self-initialisation's settings and
    ``keep_particles``."""

    local: LocalStepSettings = field(default_factory=_hybrid_local)
    apf: HybridSearchSettings = HybridSearchSettings()
    keypoints: KeypointSettings = KeypointSettings()
    initialization: InitSettings = InitSettings()
    keep_particles: bool = False
