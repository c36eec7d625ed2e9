"""Shape and pose initialisation from multi-view silhouettes (Zhang et al. 2013, Sec. 3.1).

No ground truth is used. Starting from the mean body:
1. position: the 3D point closest to the rays through the silhouette centroids of all
   views (the body's centre), which places the pelvis above it on the floor;
2. heading: a coarse search over rotations about the vertical axis, scored by E_S;
3. then ``rounds`` of alternating refinement: the pose by an annealed particle filter on E_S
   (all DOFs) followed by local optimisation on the contours, and the shape coefficients
   (the first ``shape_components``) by an annealed search on E_S with the pose held fixed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocap.body.model import BodyModel
from mocap.body.twists import se3_log
from mocap.cameras import Rig, pixel_rays, project
from mocap.energy.silhouette import SilhouetteEnergy, chamfer_energy, silhouette_target
from mocap.local.contour import ContourMatcher, observed_contours
from mocap.local.optimize import optimize_pose
from mocap.render import get_rasterizer
from mocap.trackers.apf import APFSettings, run_apf


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


def closest_point_to_rays(origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Least-squares point nearest to rays (N, 3), (N, 3) unit."""
    P = np.eye(3)[None] - directions[:, :, None] * directions[:, None, :]
    return np.linalg.solve(P.sum(axis=0), (P @ origins[..., None]).sum(axis=0))[:, 0]


def root_twist(yaw: float, x: float, y: float) -> np.ndarray:
    """Global twist of a rotation about the vertical through the origin, then a shift in x, y."""
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = [x, y]
    return se3_log(T)


def shape_energy(body: BodyModel, rig: Rig, chi: np.ndarray, target, components: int):
    """E_S as a function of the first ``components`` shape coefficients, pose fixed."""
    raster = get_rasterizer(body.faces, body.num_vertices)
    h, w = target.size
    K = body.num_shape

    def energy(a: np.ndarray) -> np.ndarray:
        alpha = np.zeros((len(a), K))
        alpha[:, :components] = a
        verts = body.pose(np.repeat(chi[None], len(a), axis=0), alpha).vertices
        px, depth = project(rig, verts, return_depth=True)
        masks = raster(px, h, w, depth, near=0.05)
        return np.nanmean(chamfer_energy(masks, target)[:, target.valid], axis=1)

    return energy


def initialize_from_silhouettes(body: BodyModel, rig: Rig, masks: np.ndarray, rng: np.random.Generator,
                                settings: InitSettings = InitSettings()
                                ) -> tuple[np.ndarray, np.ndarray, dict]:
    """(chi (D,), alpha (K,), diagnostics) estimated from one frame's masks (C, H, W)."""
    if masks is None:
        raise ValueError("silhouette initialisation needs masks")
    scale = min(1.0, settings.resolution / float(np.max(rig.sizes)))
    target = silhouette_target(masks, scale, view_names=tuple(rig.names))
    small = rig.scaled(scale)
    # 1. position from the silhouette centroids
    origins, dirs = [], []
    for c, cam in enumerate(rig):
        ys, xs = np.nonzero(masks[c])
        if len(xs):
            o, d = pixel_rays(cam, np.array([[xs.mean(), ys.mean()]]))
            origins.append(o[0])
            dirs.append(d[0])
    if len(origins) < 2:
        raise ValueError("silhouette initialisation needs the subject in at least 2 views")
    center = closest_point_to_rays(np.array(origins), np.array(dirs))
    alpha = np.zeros(body.num_shape)
    # 2. heading search with the mean body in the rest pose
    shaped = body.shaped(alpha)
    sil = SilhouetteEnergy(shaped, rig, scale)
    yaws = np.linspace(0, 2 * np.pi, settings.headings, endpoint=False)
    cands = np.zeros((len(yaws), body.num_dofs))
    for i, yaw in enumerate(yaws):
        cands[i, :6] = root_twist(yaw, center[0], center[1])
    e_head = sil(cands, target)
    best = int(np.argmin(e_head))
    diag = {"center": center.tolist(), "heading_energy": e_head.tolist()}
    std = np.r_[np.full(3, 0.05), np.full(3, 0.15), np.full(body.num_dofs - 6, 0.3)]
    obs = observed_contours(masks)
    # silhouettes hardly tell front from back: refine the best heading and its opposite
    # (one pose round each) and keep the better one
    hypotheses = []
    for yaw in (yaws[best], yaws[best] + np.pi):
        h = np.zeros(body.num_dofs)
        h[:6] = root_twist(yaw, center[0], center[1])
        h, _ = run_apf(lambda x, sil=sil: sil(x, target), h, std, body.limits,
                       APFSettings(particles=settings.pose_particles, layers=settings.pose_layers,
                                   diffusion=0.7, shrink=0.9), rng, root_point=shaped.rest_joints[0])
        matcher = ContourMatcher(body, rig)
        h, _ = optimize_pose(shaped, h, lambda v, m=matcher: m(v, obs), settings.local_iterations)
        hypotheses.append((float(sil(h[None], target)[0]), h))
    diag["heading_hypotheses_energy"] = [e for e, _ in hypotheses]
    chi = min(hypotheses, key=lambda t: t[0])[1]
    shape_std = np.full(settings.shape_components, 0.8)
    shape_limits = np.tile([-3.0, 3.0], (settings.shape_components, 1))
    for r in range(settings.rounds):
        # 3a. pose: annealed search on E_S, then local optimisation on the contours
        shaped = body.shaped(alpha)
        sil = SilhouetteEnergy(shaped, rig, scale)
        chi, _ = run_apf(lambda x, sil=sil: sil(x, target), chi, std * (0.5 ** (r + 1)), body.limits,
                         APFSettings(particles=settings.pose_particles, layers=settings.pose_layers,
                                     diffusion=0.7, shrink=0.9), rng, root_point=shaped.rest_joints[0])
        matcher = ContourMatcher(body, rig)
        chi, _ = optimize_pose(shaped, chi, lambda v, m=matcher: m(v, obs), settings.local_iterations)
        # 3b. shape: annealed search over the first components, pose fixed
        energy = shape_energy(body, small, chi, target, settings.shape_components)
        a, _ = run_apf(energy, alpha[:settings.shape_components], shape_std * (0.6**r), shape_limits,
                       APFSettings(particles=settings.shape_particles, layers=settings.shape_layers,
                                   diffusion=0.7, shrink=0.9), rng)
        alpha = alpha.copy()
        alpha[:settings.shape_components] = a
        diag[f"round_{r}_energy"] = float(energy(a[None])[0])
    shaped = body.shaped(alpha)
    matcher = ContourMatcher(body, rig)
    chi, _ = optimize_pose(shaped, chi, lambda v: matcher(v, obs), settings.local_iterations)
    return chi, alpha, diag


class SilhouetteInitialisation:
    """Mixin of the silhouette trackers: ``initial_estimate`` from frame 0's masks, and the
    validation of an initial pose. Needs ``body``, ``rig``, ``init_rng``, ``init_settings``."""

    def initial_estimate(self, frame) -> tuple[np.ndarray, np.ndarray]:
        """Shape and pose from this frame's silhouettes alone (Sec. 3.1)."""
        chi, alpha, _ = initialize_from_silhouettes(self.body, self.rig, frame.masks, self.init_rng,
                                                    self.init_settings)
        return chi, alpha

    def checked_pose(self, chi: np.ndarray) -> np.ndarray:
        chi = np.asarray(chi, np.float64)
        if chi.shape != (self.body.num_dofs,) or not np.all(np.isfinite(chi)):
            raise ValueError(f"initial pose must be a finite ({self.body.num_dofs},) vector")
        return chi
