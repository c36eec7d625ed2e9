"""Tracker constructors: :func:`build_tracker` builds a tracker from its settings dataclass,
the settings' class choosing which (:data:`BUILDERS`); the named presets
(:func:`mocap.trackers.presets.make_tracker`, for the Python API and Hydra alike) come
through it. Every default is the settings dataclass's (:mod:`mocap.trackers.tracker_settings`,
:mod:`mocap.trackers.markers.settings`)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy.prior import ParzenPrior, PosePrior, default_prior_path
from mocap.trackers.hybrid_tracker import HybridTracker, library_poses
from mocap.trackers.local_tracker import LocalTracker
from mocap.trackers.markers.settings import MarkerPeopleSettings, MarkerSettings
from mocap.trackers.silhouette_tracker import APFTracker, internal_scale  # noqa: F401  (internal_scale: re-exported)
from mocap.trackers.tracker_settings import (
    APFTrackerSettings,
    HybridSettings,
    LocalSettings,
    PriorSettings,
    SilhouetteSearchSettings,
)


def prior_file(body: BodyModel, settings: PriorSettings) -> Path:
    """The pose prior's file: ``settings.prior_file``, else the one shipped for the body from
    ``settings.prior_source`` (:func:`mocap.energy.prior.prior_path`)."""
    if settings.prior_file:
        return Path(settings.prior_file)
    try:
        from mocap.energy.prior import prior_path
    except ImportError:             # before prior sources: the procedural prior only
        if settings.prior_source != "procedural":
            raise ValueError(f"setting prior.prior_source = {settings.prior_source!r} is out of range "
                             "(allowed: 'procedural')") from None
        return default_prior_path(body.name)
    return prior_path(body.name, settings.prior_source)


def make_pose_prior(body: BodyModel, settings: PriorSettings) -> PosePrior:
    """E_P of Zhang et al. (Eq. 14): joint-limit penalty + the learned Parzen density."""
    parzen = ParzenPrior.load(prior_file(body, settings)) if settings.learned_weight else None
    return PosePrior(body.dof_names, body.limits, parzen, limit_sigma=settings.limit_sigma,
                     limit_weight=settings.limit_weight, learned_weight=settings.learned_weight)


def _pose_prior(body: BodyModel, search: SilhouetteSearchSettings) -> PosePrior | None:
    return make_pose_prior(body, search.prior) if search.energy.prior else None


def build_apf_tracker(body: BodyModel, rig: Rig, rng: np.random.Generator, settings: APFTrackerSettings,
                      name: str = "apf") -> APFTracker:
    """The silhouette APF (``apf``, ``apf_25x10``, ``apf_prior``)."""
    return APFTracker(body, rig, settings, settings.energy, rng, prior=_pose_prior(body, settings), name=name)


def build_local_tracker(body: BodyModel, rig: Rig, rng: np.random.Generator, settings: LocalSettings,
                        name: str = "local") -> LocalTracker:
    """The local tracker (``rng``: its self-initialisation's)."""
    return LocalTracker(body, rig, settings, name=name, rng=rng)


def build_hybrid_tracker(body: BodyModel, rig: Rig, rng: np.random.Generator, settings: HybridSettings,
                         name: str = "hybrid") -> HybridTracker:
    """The hybrid tracker; its restarts draw from the pose prior's training poses (and their
    mirror images) when ``apf.restart_from_library`` > 0 and the prior's file exists."""
    a = settings.apf
    library = None
    if a.restart_from_library:
        path = prior_file(body, a.prior)
        if a.prior.prior_file or path.is_file():
            lib = ParzenPrior.load(path)
            library = library_poses(body, lib.samples, lib.dof_names)
        else:
            warnings.warn(f"no pose prior shipped for body {body.name!r} ({path}): the hybrid's restarts "
                          "draw uniformly within the joint limits (apf.prior.prior_file names one)",
                          stacklevel=2)
    return HybridTracker(body, rig, rng, settings, _pose_prior(body, a), library, name=name)


def build_marker_tracker(body: BodyModel, rig: Rig, rng: np.random.Generator, settings,
                         name: str = "marker_apf"):
    """The marker tracker of Canton-Ferrer et al. 2010 (settings:
    :class:`~mocap.trackers.markers.settings.MarkerSettings`)."""
    from mocap.trackers.markers.tracker import MarkerAPFTracker

    return MarkerAPFTracker(body, rig, settings, rng, name=name)


def build_marker_people_tracker(body: BodyModel, rig: Rig, rng: np.random.Generator, settings,
                                name: str = "marker_people"):
    """Several people (``marker_people``, :class:`~mocap.trackers.markers.people.PeopleTracker`;
    settings: :class:`~mocap.trackers.markers.settings.MarkerPeopleSettings`): one marker
    tracker per person, each with the marker settings and its own generator spawned from
    ``rng`` (in the order the people are found), keeping no particles."""
    from dataclasses import replace

    from mocap.trackers.markers.people import PeopleTracker
    from mocap.trackers.markers.tracker import MarkerAPFTracker

    per_person = replace(settings, keep_particles=False)
    people = PeopleTracker(lambda: MarkerAPFTracker(body, rig, per_person, rng.spawn(1)[0], name=name),
                           settings.people, name=name)
    people.tracker_settings = settings
    return people


#: settings class -> the function building its tracker: (body, rig, rng, settings, name) -> tracker
BUILDERS = {APFTrackerSettings: build_apf_tracker, LocalSettings: build_local_tracker,
            HybridSettings: build_hybrid_tracker, MarkerSettings: build_marker_tracker,
            MarkerPeopleSettings: build_marker_people_tracker}


def build_tracker(body: BodyModel, rig: Rig, rng: np.random.Generator, settings, name: str):
    """The tracker configured by ``settings`` (an instance of a key of :data:`BUILDERS`), named
    ``name``."""
    build = BUILDERS.get(type(settings))
    if build is None:
        raise TypeError(f"no tracker is built from {type(settings).__name__} "
                        f"(settings classes: {', '.join(c.__name__ for c in BUILDERS)})")
    return build(body, rig, rng, settings, name)
