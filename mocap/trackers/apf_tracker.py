"""Silhouette trackers built on the annealed particle filter: ``apf`` (100 x 15, E_S + lambda E_R)
and ``apf_prior`` (25 x 10, with the pose prior E_P), Zhang et al. 2013, Sec. 4.2."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from mocap.body.energy_mesh import ENERGY_MESH_FACES, energy_mesh_for
from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy.prior import PosePrior
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.energy.smoothness import predict_constant_velocity
from mocap.energy.total import EnergyWeights, FrameEnergy
from mocap.trackers.apf import APFSettings, run_apf
from mocap.trackers.base import Frame
from mocap.trackers.diagnostics import StepDiagnostics
from mocap.trackers.initialization import InitSettings, SilhouetteInitialisation
from mocap.trackers.step import AnnealedStep


def diffusion_std(body: BodyModel, translation: float, rotation: float, joint: float) -> np.ndarray:
    """Initial per-DOF diffusion std (D,): the twist's v part (m), its omega part (rad), angles."""
    return np.r_[np.full(3, translation), np.full(3, rotation), np.full(body.num_dofs - 6, joint)]


class APFTracker(AnnealedStep, SilhouetteInitialisation):
    """Tracks one subject of known shape from multi-view silhouettes."""

    def __init__(self, body: BodyModel, rig: Rig, settings: APFSettings, weights: EnergyWeights,
                 rng: np.random.Generator, prior: PosePrior | None = None, scale: float = 0.25,
                 init_std: Sequence[float] = (0.03, 0.03, 0.08), prediction_damping: float = 1.0,
                 keep_particles: bool = False, name: str = "apf",
                 initialization: Mapping | None = None,
                 energy_mesh: int | None = ENERGY_MESH_FACES):
        self.body, self.rig, self.settings, self.weights = body, rig, settings, weights
        self.rng, self.prior, self.scale, self.name = rng, prior, scale, name
        self.std0 = diffusion_std(body, *init_std)
        self.damping = prediction_damping
        self.keep_particles = keep_particles
        self.init_settings = InitSettings(**dict(initialization or {}))
        self.energy_mesh = energy_mesh_for(body, energy_mesh)   # None: the full mesh
        self.init_rng = rng
        self.history: list[np.ndarray] = []
        self.shaped = None
        self.energy: SilhouetteEnergy | None = None

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
