"""The named trackers (presets): each is a settings object, the settings dataclass's defaults
with the preset's differences applied; the kind of tracker is the settings' class. This is the
only place a preset is written: the command line's ``tracker=<name>`` is the same preset,
registered with Hydra from here (:mod:`mocap_cli.conf_schema`), and both build it with
:func:`make_tracker` (``tracker.<key>=...`` overrides are its keyword overrides).

Importing this module imports none of the numeric stack (the settings modules are plain
dataclasses); :func:`make_tracker` imports the trackers when it builds one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

from mocap.settings import with_overrides
from mocap.trackers.markers.settings import MarkerPeopleSettings, MarkerSettings
from mocap.trackers.tracker_settings import (
    APFTrackerSettings,
    HybridSettings,
    InitSettings,
    LocalSettings,
    StartOverFrames,
    TrackSmoothing,
    TwoCueShape,
)

#: each tracker config's settings dataclass, whose defaults are the config's defaults
SETTINGS_CLASSES: dict[str, type] = {"apf": APFTrackerSettings, "local": LocalSettings,
                                     "hybrid": HybridSettings, "marker_apf": MarkerSettings,
                                     "marker_people": MarkerPeopleSettings}

_APF_25X10 = replace(APFTrackerSettings(), particles=25, layers=10)
_APF_PRIOR = replace(_APF_25X10, energy=replace(_APF_25X10.energy, prior=1.0))
_HYBRID_APF = HybridSettings().apf
_HYBRID_PRIOR = replace(HybridSettings(),
                        apf=replace(_HYBRID_APF, energy=replace(_HYBRID_APF.energy, prior=1.0)))
#: the hybrid whose limb-repair APF has the unconstrained budget of Zhang et al.'s Fig. 9 (100 x 15,
#: no prior): the control of the paper's claim in its own setting (docs/results/recovery.md)
_HYBRID_100X15 = replace(HybridSettings(), apf=replace(_HYBRID_APF, particles=100, layers=15))


#: the two-cue hybrid's keypoint weight (one keypoint correspondence against one contour
#: correspondence), chosen on the real-motion benchmark's dev split (docs/results/two_cue_hybrid.md)
KEYPOINT_WEIGHT = 200.0
#: its start-up shape fit to the keypoints' bone lengths (prior std around the silhouettes' shape),
#: chosen on the same dev split among 0, 1 and 3 (docs/results/real_motion.md), then among 1, 1.5
#: and 2 (issue 34: docs/results/surface.md, "Keypoint offsets")
KEYPOINT_SHAPE_STD = 1.5
#: the frames whose triangulated keypoints' median bone lengths the shape is fitted to again
#: (issue 34, chosen on the same dev split among 1 and 15: docs/results/surface.md, "accuracy push")
KEYPOINT_SHAPE_FRAMES = 15
#: its shape fitted once, after that many frames, to both cues at once (keypoints.two_cue, in place of
#: that refit and the silhouette-only refinements), every one of those frames in the silhouette term,
#: each view counted as this many samples: chosen on the same dev split among 9 variants (view samples
#: 2 to 128, aligned frames only or all; issue 34: docs/results/surface.md, "Two-cue shape over many
#: frames")
#: (16 then; 8 since its fit converges, below; 16 again since the skeleton below carries the bone lengths:
#: chosen on the same dev split among 8, 16 and 32 by the rule written before they ran, issue 34 item 4:
#: docs/results/surface.md, "The two-cue hybrid's surface with its skeleton")
TWO_CUE_VIEW_SAMPLES = 16.0
#: that fit's last step: this many iterations of a trust region on quadratic models of batched samples,
#: which goes on where Powell's line searches stall (they stopped short of the fit's own minimum: bow's
#: energy 1989 -> 1716 with it); chosen with the view samples above on the same dev split among 4 variants
#: (issue 34 item 4: docs/results/surface.md, "The two-cue hybrid's proportions")
TWO_CUE_QUADRATIC = 12
#: at that fit, the person's skeleton inside the shape's outline too: rest-joint corrections fitted to the
#: kept frames' keypoints (prior spread per coordinate, m), their poses first re-fitted on the new shape by
#: this many local steps; chosen on the same dev split by the rule written before it ran (issue 34 item 4:
#: docs/results/surface.md, "The two-cue hybrid's skeleton")
TWO_CUE_SKELETON = 0.03
TWO_CUE_SKELETON_REFIT = 1
_TWO_CUE = TwoCueShape(frames=KEYPOINT_SHAPE_FRAMES, keyframes=KEYPOINT_SHAPE_FRAMES, aligned_only=False,
                       view_samples=TWO_CUE_VIEW_SAMPLES, quadratic=TWO_CUE_QUADRATIC,
                       skeleton=TWO_CUE_SKELETON, skeleton_refit=TWO_CUE_SKELETON_REFIT)
#: its local step solved within the joint limits (an angle at its limit held while the others take up
#: what it cannot give, not clipped after the solve), chosen on the same dev split (issue 34 item 4:
#: docs/results/surface.md, "The two-cue hybrid's pose")
KEYPOINT_ACTIVE_LIMITS = True
#: its finished track smoothed (zero-phase 4th-order Butterworth at this cut-off, Hz), chosen on the same
#: dev split among 2, 3, 4, 6 and 8 Hz (issue 34 item 4: docs/results/surface.md, "The two-cue hybrid's pose")
KEYPOINT_SMOOTHING_HZ = 4.0
#: its own joint limits (the tracker's only: the body, its oracles and the other trackers keep the
#: body's): those widened from the training motion (mocap/trackers/assets), chosen on the same dev split
#: (issue 34 item 4: docs/results/surface.md, "The two-cue hybrid, next stop")
KEYPOINT_JOINT_LIMITS = "widened"
#: (its start: the plain silhouette start, which its keypoint search refines; the limb hypotheses of
#: the silhouette-only hybrid's start were chosen without keypoints, as was its start chosen over frames
#: (start_frames); nor its repair's wide search of a limb chain flagged frames in a row, apf.stuck_frames,
#: nor its patrol of the arms, apf.patrol)
_HYBRID_KP = replace(HybridSettings(), initialization=InitSettings(), start_frames=StartOverFrames(),
                     apf=replace(HybridSettings().apf, stuck_frames=0, patrol=0, patrol_chains="all",
                                 patrol_agreement=0.0, patrol_margin=0.0),
                     local=replace(HybridSettings().local, active_limits=KEYPOINT_ACTIVE_LIMITS),
                     smoothing=TrackSmoothing(cutoff_hz=KEYPOINT_SMOOTHING_HZ),
                     joint_limits=KEYPOINT_JOINT_LIMITS,
                     keypoints=replace(HybridSettings().keypoints, weight=KEYPOINT_WEIGHT,
                                       shape_std=KEYPOINT_SHAPE_STD, shape_frames=KEYPOINT_SHAPE_FRAMES,
                                       two_cue=_TWO_CUE))

#: the real-motion prior's weight, chosen on the real-motion benchmark's dev split
#: (docs/results/real_motion.md): its narrow sigma makes -log p steep
REAL_PRIOR_WEIGHT = 0.05


def _real(prior):
    """``prior`` (PriorSettings) reading the prior learned from real motion capture."""
    return replace(prior, prior_source="real", learned_weight=REAL_PRIOR_WEIGHT)


#: name -> the preset's settings (its class says which tracker: :data:`SETTINGS_CLASSES`)
PRESETS: dict[str, Any] = {
    "apf": APFTrackerSettings(),
    "apf_25x10": _APF_25X10,
    "apf_prior": _APF_PRIOR,
    "apf_prior_real": replace(_APF_PRIOR, prior=_real(_APF_PRIOR.prior)),
    "local": LocalSettings(),
    "hybrid": HybridSettings(),
    "hybrid_prior": _HYBRID_PRIOR,
    "hybrid_100x15": _HYBRID_100X15,
    "hybrid_prior_real": replace(_HYBRID_PRIOR,
                                 apf=replace(_HYBRID_PRIOR.apf, prior=_real(_HYBRID_PRIOR.apf.prior))),
    "hybrid_kp": _HYBRID_KP,
    "marker_apf": MarkerSettings(),
    "marker_people": MarkerPeopleSettings(),
}


def preset_settings(name: str, overrides: Mapping | None = None):
    """The settings of tracker ``name`` (a key of :data:`PRESETS`) with ``overrides`` (nested
    mappings update nested settings key by key; unknown keys and out-of-range values raise a
    one-line ValueError naming the key)."""
    if name not in PRESETS:
        raise ValueError(f"unknown tracker {name!r}; available: {', '.join(sorted(PRESETS))}")
    return with_overrides(PRESETS[name], overrides)


def make_tracker(name: str, *, body, rig, rng, **overrides):
    """The tracker ``name`` (a preset) with ``overrides`` of its settings (e.g. ``particles=50``,
    ``energy={"smoothness": 0.1}``); the one builder of a named tracker, for the Python API and
    for Hydra (``_target_`` of every ``tracker=<name>`` node, which passes the whole settings
    tree as overrides)."""
    from mocap.trackers.factory import build_tracker

    return build_tracker(body, rig, rng, preset_settings(name, overrides), name)
