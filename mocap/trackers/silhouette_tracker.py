"""Silhouette trackers built on the annealed particle filter: ``apf`` (E_S + lambda E_R) and
``apf_prior`` (a smaller budget, with the pose prior E_P), Zhang et al. 2013, Sec. 4.2; their
settings: :class:`~mocap.trackers.tracker_settings.APFTrackerSettings`, the presets
:mod:`mocap.trackers.presets`."""

from __future__ import annotations

import dataclasses

import numpy as np

from mocap.body.energy_mesh import energy_mesh_for
from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy.prior import PosePrior
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.energy.smoothness import predict_constant_velocity
from mocap.energy.total import FrameEnergy
from mocap.energy.weights import EnergyWeights
from mocap.settings import fields_of
from mocap.trackers.annealed_step import AnnealedStep
from mocap.trackers.apf import run_apf
from mocap.trackers.base import Frame
from mocap.trackers.contract import Needs, OnePerson, SearchBudget
from mocap.trackers.diagnostics import StepDiagnostics
from mocap.trackers.init_cache import SilhouetteInitialisation
from mocap.trackers.tracker_settings import APFSettings, APFTrackerSettings


def diffusion_std(body: BodyModel, translation: float, rotation: float, joint: float) -> np.ndarray:
    """Initial per-DOF diffusion std (D,): the twist's v part (m), its omega part (rad), angles."""
    return np.r_[np.full(3, translation), np.full(3, rotation), np.full(body.num_dofs - 6, joint)]


def internal_scale(rig: Rig, resolution: int) -> float:
    """Scale factor that brings the rig's longer image side to ``resolution`` px (<= 1)."""
    return rig.scale_for(resolution)


class APFTracker(AnnealedStep, SilhouetteInitialisation, OnePerson):
    """Tracks one subject of known shape from multi-view silhouettes.

    settings: the tracker's settings (a bare :class:`APFSettings`: that search, the rest at
    :class:`APFTrackerSettings`' defaults); weights: the energy weights (the settings' own
    by default); prior: the pose prior when ``weights.prior``; scale: the internal
    silhouette scale (by default ``settings.resolution`` px on the longer image side)."""

    needs = Needs(masks=True)

    def __init__(self, body: BodyModel, rig: Rig, settings: APFTrackerSettings | APFSettings,
                 weights: EnergyWeights | None, rng: np.random.Generator, prior: PosePrior | None = None,
                 scale: float | None = None, name: str = "apf"):
        if not isinstance(settings, APFTrackerSettings):
            settings = APFTrackerSettings(**fields_of(settings, APFSettings))
        self.tracker_settings = settings
        self.body, self.rig, self.settings = body, rig, settings.search
        self.weights = settings.energy if weights is None else weights
        self.rng, self.prior, self.name = rng, prior, name
        self.scale = internal_scale(rig, settings.resolution) if scale is None else scale
        self.std0 = diffusion_std(body, *settings.init_std)
        self.damping = settings.prediction_damping
        self.keep_particles = settings.keep_particles
        self.init_settings = settings.initialization
        self.energy_mesh = energy_mesh_for(body, settings.energy_mesh)   # None: the full mesh
        self.init_rng = rng
        self.history: list[np.ndarray] = []
        self.shaped = None
        self.energy: SilhouetteEnergy | None = None

    @property
    def budget(self) -> SearchBudget:
        return SearchBudget(self.settings.particles, self.settings.layers, tuple(self.weights.terms))

    def initialize(self, chi: np.ndarray, alpha: np.ndarray) -> None:
        chi = self.checked_pose(chi)
        self.shaped = self.body.shaped(alpha)
        self.energy = SilhouetteEnergy(self.shaped, self.rig, self.scale, mesh=self.energy_mesh)
        self.history = [chi]

    def predict(self) -> np.ndarray:
        return predict_constant_velocity(self.history[-2:], self.damping)

    def frame_energy(self, frame: Frame, predicted: np.ndarray,
                     dof_mask: np.ndarray | None = None) -> tuple[FrameEnergy, tuple[str, ...]]:
        if frame.masks is None:
            raise ValueError(f"frame {frame.index}: the silhouette trackers need masks")
        target = silhouette_target(frame.masks, self.scale, view_names=tuple(self.rig.names))
        return FrameEnergy(self.weights, self.energy, target, predicted, self.prior, dof_mask), target.ignored

    def search(self, energy: FrameEnergy, predicted: np.ndarray):
        return run_apf(energy, predicted, self.std0, self.body.limits, self.settings, self.rng,
                       keep_particles=self.keep_particles, previous=self.history[-1],
                       root_point=self.shaped.rest_joints[0])

    def report(self, energy, ignored, chi, trace, timings) -> StepDiagnostics:
        return dataclasses.replace(super().report(energy, ignored, chi, trace, timings),
                                   ignored_views=tuple(ignored))
