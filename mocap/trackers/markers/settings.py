"""The marker tracker's settings (``marker_apf``): one frozen dataclass, the only place its
defaults are written, with nested settings for the start-up (:class:`MarkerInit`), the
per-frame refinement (:class:`Refinement`, used by :mod:`mocap.trackers.markers.refine`) and the learned
keypoint offsets (:class:`~mocap.trackers.markers.offsets.OffsetLearning`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from mocap.energy.marker_likelihood import MarkerLikelihood
from mocap.settings import check, fields_of
from mocap.trackers.tracker_settings import APFSettings, OffsetLearning

#: detector profiles: keypoint type -> mean (out, forward, up) offset in mm
#: (:mod:`mocap.trackers.markers.offsets` explains them).
#: ``realistic_sim``: the simulated detector of ``data.detections.semantics=realistic``, calibrated
#: on the real-motion DEV split and data/mismatch (8 views, seeds 0-2): the mean of robust
#: triangulations of its detections against the ground-truth joints
#: (``python experiments/detector_semantics.py --calibrate``)
PROFILES: dict[str, dict[str, tuple[float, float, float]]] = {
    "realistic_sim": {"mid_hip": (-1.0, 4.0, 44.0), "neck_base": (-1.0, 13.0, 18.0),
                      "head_centre": (-1.0, 26.0, 10.0), "shoulder": (12.0, -8.0, 22.0),
                      "elbow": (8.0, -13.0, 0.0), "wrist": (-1.0, 8.0, -6.0), "hip": (21.0, 5.0, 45.0),
                      "knee": (-1.0, 18.0, 1.0), "ankle": (4.0, -4.0, -12.0)},
}


@dataclass(frozen=True)
class Refinement:
    """iterations: 0 disables; gate_px: association radius (None: the likelihood's gate);
    huber_px: robust scale; prior_std: per-DOF prior width around the APF estimate;
    use_confidence: weight residuals by detection confidence; outlier_views: down-weight a
    view whose median residual exceeds this many times the views' median (0: off); step:
    finite difference."""

    iterations: int = 3
    gate_px: float | None = None
    huber_px: float = 4.0
    prior_std: float = 0.1
    use_confidence: bool = True
    outlier_views: float = 0.0
    step: float = 1e-4
    damping: float = 1e-3

    def __post_init__(self) -> None:
        check(self, "iterations", self.iterations >= 0, "an integer >= 0 (0: off)")
        check(self, "gate_px", self.gate_px is None or self.gate_px > 0, "null or > 0 px")
        check(self, "huber_px", self.huber_px > 0, "> 0 px")
        check(self, "prior_std", self.prior_std > 0, "> 0")
        check(self, "outlier_views", self.outlier_views == 0 or self.outlier_views > 1, "0 (off) or > 1")
        check(self, "step", self.step > 0, "> 0")
        check(self, "damping", self.damping >= 0, ">= 0")


@dataclass(frozen=True)
class MarkerInit:
    """Self-initialisation: passes of annealed inverse kinematics to the triangulated
    landmarks (particles x layers each, first-pass diffusion ``std`` = (translation m,
    rotation rad, joints rad) shrinking by ``shrink`` per pass); ``length_sigma``: the
    bone-length noise (m) of the shape fit; ``fit_shape``: False keeps the mean shape;
    ``outlier_sigma``: measured distances this many shape-model sigmas from their mean are
    ignored by the fit; ``bound_sigma``: a fitted bone outside the model's mean +- this many
    sigmas makes the start-up shrink the fitted coefficients towards the mean until every bone
    is inside (flagged); ``association_px``: the
    skeleton epipolar threshold of the cross-view association (None: the gate);
    ``refine_iterations``: Gauss-Newton steps on the reprojection error that pose each shape
    hypothesis before it is scored (0: scored at the annealed IK's pose)."""

    passes: int = 3
    particles: int = 300
    layers: int = 10
    std: tuple[float, float, float] = (0.1, 0.3, 0.6)
    shrink: float = 0.4
    length_sigma: float = 0.02
    fit_shape: bool = True
    # wide enough that a tall subject's legs, or hips marked 5 cm high, keep their leg bones
    # (docs/results/detector_semantics.md)
    outlier_sigma: float = 8.0
    bound_sigma: float = 6.0
    association_px: float | None = None
    refine_iterations: int = 10

    def __post_init__(self) -> None:
        object.__setattr__(self, "std", tuple(float(v) for v in self.std))
        check(self, "passes", self.passes >= 1, "an integer >= 1")
        check(self, "particles", self.particles >= 2, "an integer >= 2")
        check(self, "layers", self.layers >= 1, "an integer >= 1")
        check(self, "std", len(self.std) == 3 and min(self.std) >= 0, "3 numbers >= 0")
        check(self, "shrink", 0.0 < self.shrink <= 1.0, "(0, 1]")
        check(self, "length_sigma", self.length_sigma > 0, "> 0 m")
        check(self, "outlier_sigma", self.outlier_sigma > 0, "> 0")
        check(self, "bound_sigma", self.bound_sigma > 0, "> 0")
        check(self, "association_px", self.association_px is None or self.association_px > 0,
              "null or > 0 px")
        check(self, "refine_iterations", self.refine_iterations >= 0, "an integer >= 0")


@dataclass(frozen=True)
class MarkerSettings(APFSettings):
    """``marker_apf`` (Canton-Ferrer et al. 2010): the annealed search (fewer layers, a lower
    survival rate and a faster shrink than the silhouette APF's; ``crossover``: each limb
    resampled by its own landmarks), its
    first-layer diffusion ``init_std`` (twist v m, twist omega rad, angles rad), the
    constant-velocity prediction's ``prediction_damping``; the likelihood
    (:class:`~mocap.energy.markers.MarkerLikelihood`: ``gate`` the outlier threshold tau as a
    fraction of the image diagonal, ``min_views``, ``coherence_radius`` m,
    ``coherence_weight``, ``use_confidence``); ``landmarks``: ``auto`` (every detection label
    the catalogue knows) or a list of names / landmark entries; ``min_confidence``: drop
    detections below it; the start-up (``init``), the refinement (``refine``), the offsets
    (``offsets``), ``keypoint_profile``: the detector profile (the mean offsets of the
    detector's keypoints from the joints, :data:`mocap.trackers.markers.offsets.PROFILES`):
    ``auto`` (the one the sequence's detections declare in their meta, e.g. ``realistic_sim``
    for ``data.detections.semantics=realistic``; none otherwise), null (none) or a profile's
    name; and ``keep_particles``."""

    layers: int = 6
    survival: float = 0.25
    shrink: float = 0.85
    crossover: bool = True
    init_std: tuple[float, float, float] = (0.02, 0.03, 0.12)
    prediction_damping: float = 1.0
    gate: float = 0.04
    min_views: int = MarkerLikelihood.min_views
    coherence_radius: float = MarkerLikelihood.coherence_radius
    coherence_weight: float = MarkerLikelihood.coherence_weight
    use_confidence: bool = MarkerLikelihood.use_confidence
    landmarks: str | tuple = "auto"
    min_confidence: float = 0.0
    init: MarkerInit = MarkerInit()
    refine: Refinement = Refinement()
    offsets: OffsetLearning = OffsetLearning()
    keypoint_profile: str | None = "auto"
    keep_particles: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        check(self, "init_std", len(self.init_std) == 3 and min(self.init_std) >= 0, "3 numbers >= 0")
        check(self, "prediction_damping", 0.0 <= self.prediction_damping <= 1.0, "[0, 1]")
        check(self, "gate", 0.0 < self.gate <= 1.0, "(0, 1], a fraction of the image diagonal")
        check(self, "min_views", self.min_views >= 1, "an integer >= 1")
        check(self, "coherence_radius", self.coherence_radius > 0, "> 0 m")
        check(self, "coherence_weight", self.coherence_weight >= 0, ">= 0")
        check(self, "min_confidence", 0.0 <= self.min_confidence <= 1.0, "[0, 1]")
        check(self, "keypoint_profile", self.keypoint_profile in (None, "auto", *PROFILES),
              f"auto, null or one of {sorted(PROFILES)}")
        check(self, "landmarks", isinstance(self.landmarks, str | tuple),
              "a landmark set's name (auto) or a list of landmark names / entries")

    @property
    def search(self) -> APFSettings:
        """The annealing search alone."""
        return APFSettings(**fields_of(self, APFSettings))

    def likelihood(self, image_sizes) -> MarkerLikelihood:
        """The likelihood for cameras of ``image_sizes`` (C, 2) px: the gate in pixels is
        ``gate`` times the mean image diagonal (numpy imported here: the settings import none)."""
        import numpy as np

        diagonal = float(np.hypot(*np.asarray(image_sizes, np.float64).mean(axis=0)))
        return MarkerLikelihood(gate_px=self.gate * diagonal, min_views=self.min_views,
                                coherence_radius=self.coherence_radius,
                                coherence_weight=self.coherence_weight, use_confidence=self.use_confidence)

    def landmark_spec(self) -> str | list:
        """``landmarks`` as :func:`mocap.body.catalogue.make_landmark_set` reads it."""
        if isinstance(self.landmarks, str):
            return self.landmarks
        return [x if isinstance(x, str) else dict(x) for x in self.landmarks]


@dataclass(frozen=True)
class PeopleOptions:
    """Several people (``marker_people``, :mod:`mocap.trackers.markers.people`): ``min_views``:
    views a person must be associated in (start-up and newcomers): 2, what triangulation needs;
    ``support``: and more than this fraction of the views that should see it
    (:meth:`views_needed`; the views whose image holds its keypoints,
    :func:`mocap.trackers.markers.associate.views_expected`): a false skeleton a detector sees
    in two views of five that all look at that place never becomes a track, a person outside the
    other cameras' images does (0: ``min_views`` alone); ``hidden``: once tracked, a view where
    another tracked person nearer the camera covers this fraction of its keypoints' box does not
    count against it (occlusion); ``confirm_frames``: a newcomer (skeletons no track took,
    consistent across the views needed) gets a track once seen in this many consecutive frames,
    each time within ``radius`` m (its triangulated keypoints' median) of where it was the frame
    before and farther than ``radius`` from every live track; ``max_missed``: a track with no
    skeleton assigned in any view for more frames than this ends (the person left; the frames it
    coasted after its last skeleton are dropped); ``max_under_viewed``: a track assigned
    skeletons in fewer views than needed (its support gone) for more consecutive frames than
    this ends too (a ghost that took a false skeleton; the frames after its last frame seen in
    the views needed are dropped); ``consistency``: a person is started (at the start-up or as a
    newcomer) only when the mean pairwise epipolar distance of its skeletons across views is at
    most this many times the frame's reference, the median of that distance over the people
    already tracked (their assigned skeletons; at the start-up over the people associated): a
    real person's views agree to the detector's noise, a chance agreement of false skeletons
    several times more loosely (0: off); ``births``: False tracks only the people of the first
    frame."""

    min_views: int = 2
    support: float = 0.5
    hidden: float = 0.75
    confirm_frames: int = 3
    max_missed: int = 10
    max_under_viewed: int = 10
    radius: float = 0.3
    consistency: float = 3.0
    births: bool = True

    def __post_init__(self) -> None:
        check(self, "min_views", self.min_views >= 2, "an integer >= 2 (a person is triangulated)")
        check(self, "support", 0 <= self.support < 1, "in [0, 1)")
        check(self, "hidden", 0 < self.hidden <= 1, "in (0, 1]")
        check(self, "confirm_frames", self.confirm_frames >= 1, "an integer >= 1")
        check(self, "max_missed", self.max_missed >= 0, "an integer >= 0")
        check(self, "max_under_viewed", self.max_under_viewed >= 0, "an integer >= 0")
        check(self, "radius", self.radius > 0, "> 0 m")
        check(self, "consistency", self.consistency == 0 or self.consistency >= 1, "0 (off) or >= 1")

    def views_needed(self, expected: int) -> int:
        """Views a person must be seen in when ``expected`` views should see it: ``min_views``,
        and more than ``support`` x ``expected`` (with 0.5: 3 of 4 or 5, 2 of 2 or 3)."""
        return max(self.min_views, math.floor(self.support * expected) + 1)


@dataclass(frozen=True)
class MarkerPeopleSettings(MarkerSettings):
    """``marker_people``: one marker tracker per person, each with these marker settings
    (:class:`MarkerSettings`; ``keep_particles`` is ignored: per-person trackers keep none),
    and how people are found, confirmed and ended (``people``: :class:`PeopleOptions`)."""

    people: PeopleOptions = PeopleOptions()
