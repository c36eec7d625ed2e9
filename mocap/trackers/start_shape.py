"""The start's shape searched together with its pose (issue 34 item 4): the last step of the
silhouette start (:mod:`mocap.trackers.initialization`, ``InitSettings.shape_pose_searches``).

The start alternates a pose search with the shape held and a shape search with the pose held.
Where one frame's silhouettes are fitted better by another shape *and* another pose at once (a
longer thigh with a less bent knee, wider hips with the legs further apart), neither step moves
alone: changing the shape with the pose held pushes the limbs off their silhouettes, and the
pose search never sees another shape. One annealed search over the pose's D DOFs and C shape
coefficients together does not find it either (measured on the real-motion dev walk's frame 0: a
random step moves every DOF at once, and a draw of one hip angle with a spread of 0.075 rad alone
raises the median E_S by 30-60 %). Here
the pose *follows* the shape: :func:`pose_compensation` linearises the posed vertices at the start
and solves for the pose change M (D, C) that keeps the surface where it is per unit of shape
change, and the search runs over the shape alone, each particle posed at chi + M (a - a0) and
scored by E_S of the body with its own shape (:func:`shape_pose_energy`; ``shape_pose_pose_scale``
> 0 adds the pose's own diffusion). Each search starts from the best so far (re-linearised
there); its result, or that after the contour step on its shape, whichever has the lower fine
E_S (the energy that ranks the start's hypotheses), replaces the start only where it lowers the
start's fine E_S, so the start's fine E_S can only fall.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mocap.body.energy_mesh import EnergyMesh
from mocap.body.model import BodyModel
from mocap.cameras import Rig
from mocap.energy import fused
from mocap.energy.silhouette import SilhouetteTarget
from mocap.trackers.apf import run_apf
from mocap.trackers.shape_search import particle_energies, posed_vertices
from mocap.trackers.tracker_settings import APFSettings

#: shape coefficients' search range (standardised PCA units), as the start's shape search
SHAPE_LIMIT = 3.0


def pose_compensation(body: BodyModel, chi: np.ndarray, alpha: np.ndarray, components: int,
                      step: float = 1e-3) -> np.ndarray:
    """M (D, C): the change of the pose chi (D,) per unit change of the first C shape coefficients
    of alpha (K,) that keeps the posed vertices nearest to where they are (least squares over all
    vertices, linearised at (chi, alpha) by central differences of ``step``): a longer thigh comes
    with a less bent hip, so that the leg stays on its silhouette."""
    chi = np.asarray(chi, np.float64)
    alpha = np.asarray(alpha, np.float64)
    D, C = body.num_dofs, int(components)
    chis = np.repeat(chi[None], 2 * (D + C), axis=0)
    shapes = np.repeat(alpha[None], 2 * (D + C), axis=0)
    for k in range(D):
        chis[2 * k, k] += step
        chis[2 * k + 1, k] -= step
    for k in range(C):
        shapes[2 * (D + k), k] += step
        shapes[2 * (D + k) + 1, k] -= step
    v = posed_vertices(body, chis, shapes).astype(np.float64).reshape(2 * (D + C), -1)
    J = ((v[0::2] - v[1::2]) / (2 * step)).T                 # (3V, D + C)
    Jp, Js = J[:, :D], J[:, D:]
    A = Jp.T @ Jp
    return -np.linalg.solve(A + 1e-9 * np.trace(A) / D * np.eye(D), Jp.T @ Js)


def shape_pose_energy(body: BodyModel, rig: Rig, target: SilhouetteTarget, alpha: np.ndarray,
                      components: int, mesh: EnergyMesh | None = None,
                      follow: tuple[np.ndarray, np.ndarray] | None = None
                      ) -> Callable[[np.ndarray], np.ndarray]:
    """E_S as a function of particles x (P, D + components) -> (P,): x[:, :D] the pose, x[:, D:]
    the first ``components`` shape coefficients (the others those of ``alpha`` (K,)); the mean
    over ``target``'s valid views of the chamfer of the body posed with its own shape, seen by
    ``rig`` (at the target's resolution), rasterised on ``mesh`` (None: the full mesh).
    follow: (M (D, C), a0 (C,)): the pose is x[:, :D] + (x[:, D:] - a0) M^T
    (:func:`pose_compensation`: the pose moves with the shape), clipped to the joint limits."""
    D, C = body.num_dofs, int(components)
    if not 1 <= C <= body.num_shape:
        raise ValueError(f"shape components must be in [1, {body.num_shape}], got {components}")
    faces = body.faces if mesh is None else mesh.faces
    nv = body.num_vertices if mesh is None else mesh.num_vertices
    kernel = fused.FusedSilhouetteEnergy(faces, nv)
    base = np.asarray(alpha, np.float64)

    def posed(x: np.ndarray) -> np.ndarray:
        if follow is None:
            return x[:, :D]
        M, a0 = follow
        return np.clip(x[:, :D] + (x[:, D:] - a0) @ M.T, body.limits[:, 0], body.limits[:, 1])

    def energy(x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(np.asarray(x, np.float64))
        if x.shape[1] != D + C:
            raise ValueError(f"shape-and-pose particles need {D + C} columns, got {x.shape[1]}")
        shapes = np.repeat(base[None], len(x), axis=0)
        shapes[:, :C] = x[:, D:]
        per_view = particle_energies(body, rig, target, posed(x), shapes, mesh=mesh, kernel=kernel)
        return np.nanmean(per_view[:, target.valid], axis=1)

    energy.pose = posed             # particles (P, D + C) -> the poses (P, D) they are scored with
    return energy


def search_shape_with_pose(body: BodyModel, chi: np.ndarray, alpha: np.ndarray,
                           make_energy: Callable[[np.ndarray, np.ndarray], Callable],
                           fine_energy: Callable[[np.ndarray, np.ndarray], float],
                           local: Callable[[np.ndarray, np.ndarray], np.ndarray],
                           components: int, pose_std: np.ndarray, shape_std: float, searches: int,
                           apf: APFSettings, rng: np.random.Generator
                           ) -> tuple[np.ndarray, np.ndarray, list[dict]]:
    """``searches`` annealed searches over the pose chi (D,) and the first C = ``components``
    shape coefficients of alpha (K,) together, one after the other, each from the best so far.

    make_energy(chi, alpha) -> energy: particles (P, D + C) -> (P,), with ``energy.pose``
    (P, D + C) -> (P, D) the poses it scores (:func:`shape_pose_energy`, built at each search's
    start); fine_energy(alpha, chi) -> float, the energy that decides; local(alpha, chi) -> chi,
    the contour step on a shape; pose_std (D,) (zeros: the pose only follows the shape), shape_std:
    first-layer spreads. A search's result, or that after ``local``, whichever has the lower fine
    energy, replaces the start where that is lower than the start's. Returns (chi, alpha, per
    search: its fine energy before and after and whether it was kept)."""
    chi = np.asarray(chi, np.float64)
    alpha = np.asarray(alpha, np.float64)
    D, C = body.num_dofs, int(components)
    limits = np.vstack([body.limits, np.tile([-SHAPE_LIMIT, SHAPE_LIMIT], (C, 1))])
    std = np.r_[np.asarray(pose_std, np.float64), np.full(C, float(shape_std))]
    free = std > 0
    best = fine_energy(alpha, chi)
    report = []
    for _ in range(searches):
        energy = make_energy(chi, alpha)
        x0 = np.clip(np.r_[chi, alpha[:C]], limits[:, 0], limits[:, 1])
        root = body.shaped(alpha).rest_joints[0]
        x, _ = run_apf(energy, x0, std, limits, apf, rng, free=free, root_point=root)
        a = alpha.copy()
        a[:C] = x[D:]
        pose = energy.pose(x[None])[0]
        # the contour step can undo what the search found (its contours are matched, not its
        # areas): the lower of the two
        e, c = min(((fine_energy(a, c), c) for c in (pose, local(a, pose))), key=lambda t: t[0])
        kept = e < best
        report.append({"before": best, "after": e, "kept": bool(kept), "coarse": float(energy(x[None])[0]),
                       "coarse_start": float(energy(x0[None])[0]),
                       "shape": [round(float(v), 3) for v in a[:C]]})
        if kept:
            best, chi, alpha = e, c, a
    return chi, alpha, report


def shape_pose_step(body: BodyModel, rig: Rig, target: SilhouetteTarget, mesh: EnergyMesh | None,
                    fine_energy: Callable[[np.ndarray, np.ndarray], float],
                    local: Callable[[np.ndarray, np.ndarray], np.ndarray], chi: np.ndarray,
                    alpha: np.ndarray, settings, pose_std: np.ndarray, rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray, list[dict]]:
    """The start's last step with ``settings`` (:class:`InitSettings`: ``shape_pose_searches``
    searches of ``shape_pose_particles`` x ``shape_pose_layers`` over the first
    ``shape_components`` coefficients, the pose following the shape (:func:`pose_compensation`)
    and searched with it from a first-layer spread ``pose_std`` (D,) times
    ``shape_pose_pose_scale``; the shape's first-layer spread ``shape_pose_shape_std``), E_S on
    ``target`` seen by ``rig`` (the pose searches' resolution) on ``mesh``; see
    :func:`search_shape_with_pose`."""
    C = min(settings.shape_components, body.num_shape)

    def make_energy(c: np.ndarray, a: np.ndarray):
        follow = (pose_compensation(body, c, a, C), np.asarray(a[:C], np.float64))
        return shape_pose_energy(body, rig, target, a, C, mesh, follow=follow)

    apf = APFSettings(particles=settings.shape_pose_particles, layers=settings.shape_pose_layers,
                      diffusion=0.7, shrink=0.9, estimate="best")
    return search_shape_with_pose(body, chi, alpha, make_energy, fine_energy, local, C,
                                  np.asarray(pose_std) * settings.shape_pose_pose_scale,
                                  settings.shape_pose_shape_std, settings.shape_pose_searches, apf, rng)
