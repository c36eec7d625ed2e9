"""The body's shape searched on silhouettes with its poses held: the initialiser's shape step
(one frame, :mod:`mocap.trackers.initialization`) and the trackers' shape refinement while
tracking (several frames, :func:`refine_shape`).

One frame's silhouettes hardly tell a long thigh from a bent knee; frames that see the body
in different poses do. :func:`refine_shape` therefore scores a shape by the silhouette energy
E_S averaged over keyframes, each posed as tracked, and keeps it only where that is lower
than the current shape's at a finer resolution than the search's (so a shape fitted to the
search's coarse masks is not taken for a better one).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocap.body.dofs import resolve_axes
from mocap.body.energy_mesh import EnergyMesh
from mocap.body.kinematics import chain_transforms
from mocap.body.lbs import lbs
from mocap.body.model import BodyModel
from mocap.body.twists import se3_exp, se3_log
from mocap.cameras import Rig, camera_coordinates, project
from mocap.compiled import HAVE_NUMBA, njit
from mocap.energy import fused
from mocap.energy.silhouette import SilhouetteEnergy, SilhouetteTarget, chamfer_energy, silhouette_target
from mocap.render import get_rasterizer
from mocap.trackers.apf import run_apf
from mocap.trackers.tracker_settings import APFSettings, ShapeRefinement


def shifted(chi: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """The pose chi (D,) with its body moved by ``shift`` (3,) world metres."""
    T = se3_exp(np.asarray(chi[:6], np.float64))
    T[:3, 3] += shift
    out = np.array(chi, np.float64)
    out[:6] = se3_log(T)
    return out


if HAVE_NUMBA:
    @njit(cache=True)
    def _blend(blended, rest, out):                # pragma: no cover - compiled
        """out[p, v, i] = B[v, 12p + 4i + 3] + sum_b B[v, 12p + 4i + b] rest[p, v, b], the
        terms added in :func:`mocap.body.lbs.lbs`'s order (the same rounding)."""
        for p in range(out.shape[0]):
            for v in range(out.shape[1]):
                for i in range(3):
                    k = 12 * p + 4 * i
                    o = blended[v, k + 3]
                    o = o + blended[v, k] * rest[p, v, 0]
                    o = o + blended[v, k + 1] * rest[p, v, 1]
                    o = o + blended[v, k + 2] * rest[p, v, 2]
                    out[p, v, i] = o


def posed_vertices(body: BodyModel, chis: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """``body.pose(chis, shapes).vertices``, (P, D), (P, K) -> (P, V, 3), the same numbers: the
    skinning's blend in one compiled pass (numpy's strided passes over the blended transforms
    cost 4x as much), without the joints the search does not read."""
    chis = np.asarray(chis, body.dtype)
    verts, joints = body.rest(shapes)
    axes = resolve_axes(body.dofs, body.joint_names, joints)
    G = chain_transforms(body.parents, body.dof_joint, axes, joints, chis[:, :6], chis[:, 6:])
    if not HAVE_NUMBA:
        return lbs(body.weights, verts, G)
    P, J = G.shape[:2]
    blended = body.weights @ G[:, :, :3, :].transpose(1, 0, 2, 3).reshape(J, -1)     # (V, 12P)
    if blended.dtype != verts.dtype:
        return lbs(body.weights, verts, G)
    out = np.empty(verts.shape, blended.dtype)
    _blend(blended, verts, out)
    return out


def particle_energies(body: BodyModel, rig: Rig, target: SilhouetteTarget, chis: np.ndarray,
                      shapes: np.ndarray, shift: np.ndarray | None = None, mesh=None, kernel=None,
                      raster=None) -> np.ndarray:
    """E_S per particle and view, (P, C) (every view, valid or not), of the body posed at chis
    (P, D) with each particle's own shape (P, K) (:func:`posed_vertices`), on ``mesh`` (an
    :class:`~mocap.body.energy_mesh.EnergyMesh`; None: the full mesh), moved by ``shift`` (P, 3)
    world metres (None: not moved), seen by ``rig`` at ``target``'s resolution: by ``kernel``
    (:class:`mocap.energy.fused.FusedSilhouetteEnergy`) when given, else rasterised by ``raster``
    (:func:`mocap.render.get_rasterizer`'s) and scored by :func:`chamfer_energy`. The one E_S of
    per-particle shapes that the shape searches (:func:`shape_energy`, the two-cue fit's
    silhouettes, the start's shape-with-pose search) score with."""
    verts = posed_vertices(body, chis, shapes)
    if mesh is not None:
        verts = mesh.apply(verts)
    if shift is not None:
        verts = verts + shift[:, None].astype(verts.dtype)
    if kernel is not None:
        return kernel(camera_coordinates(rig, verts), rig, target, near=0.05)
    px, depth = project(rig, verts, return_depth=True)
    h, w = target.size
    return chamfer_energy(raster(px, h, w, depth, near=0.05), target)


def shape_energy(body: BodyModel, rig: Rig, chis: np.ndarray, targets, components: int,
                 translate: bool = False, alpha: np.ndarray | None = None, compiled: bool = False,
                 per_view: bool = False, mesh: EnergyMesh | None = None, kernel=None):
    """E_S as a function of the first ``components`` shape coefficients: a function of
    (P, components) -> (P,), the mean over frames of E_S with the poses chis (N, D) (or one
    pose (D,)) held, against ``targets`` (one :class:`SilhouetteTarget` per pose, at ``rig``'s
    resolution). The other coefficients are those of ``alpha`` (None: zeros). With
    ``translate``, (P, components + 3): three more coordinates shift every posed body by the
    same world offset (metres; a taller body on the same root would push its feet through
    the floor). ``compiled``: the compiled kernel of :mod:`mocap.energy.fused` (rasterise and
    chamfer in one pass per particle-view, as :class:`SilhouetteEnergy` runs it: the same
    energies up to summation order) when numba imports, instead of the scanline rasterizer
    and :func:`chamfer_energy` (which the trackers' shape refinement keeps). ``per_view``: the
    function returns instead each pose's E_S per particle and view, N of (P, C), NaN in the
    target's invalid views (:func:`particle_energies`). ``mesh``: an
    :class:`~mocap.body.energy_mesh.EnergyMesh` rasterised instead of the full mesh (None).
    ``kernel``: another kernel with the fused one's call (the initialiser's early layers:
    :class:`mocap.energy.point_chamfer.PointChamfer`), used instead of it when given."""
    chis = np.atleast_2d(np.asarray(chis, np.float64))
    if isinstance(targets, SilhouetteTarget):
        targets = [targets]
    if len(targets) != len(chis):
        raise ValueError(f"{len(chis)} poses for {len(targets)} silhouette targets")
    faces, num_vertices = (body.faces, body.num_vertices) if mesh is None else (mesh.faces, mesh.num_vertices)
    raster = get_rasterizer(faces, num_vertices)
    if kernel is None:
        kernel = (fused.FusedSilhouetteEnergy(faces, num_vertices)
                  if compiled and fused.numba_available() else None)
    base = np.zeros(body.num_shape) if alpha is None else np.asarray(alpha, np.float64)

    def views(a: np.ndarray) -> list[np.ndarray]:
        a = np.atleast_2d(a)
        shapes = np.repeat(base[None], len(a), axis=0)
        shapes[:, :components] = a[:, :components]
        shift = a[:, components:components + 3] if translate else None
        return [particle_energies(body, rig, target, np.repeat(chi[None], len(a), axis=0), shapes, shift,
                                  mesh=mesh, kernel=kernel, raster=raster)
                for chi, target in zip(chis, targets, strict=True)]

    if per_view:
        return lambda a: [np.where(t.valid, e, np.nan) for e, t in zip(views(a), targets, strict=True)]

    def energy(a: np.ndarray) -> np.ndarray:
        total = np.zeros(len(np.atleast_2d(a)))
        for e, target in zip(views(a), targets, strict=True):
            total += np.nanmean(e[:, target.valid], axis=1)
        return total / len(chis)

    return energy


@dataclass(frozen=True)
class ShapeResult:
    """One refinement: the shape (K,) and shift (3,) found, E_S of the keyframes at the check
    resolution before and after, whether it was kept, and the frames it used."""

    alpha: np.ndarray
    shift: np.ndarray
    energy_before: float
    energy_after: float
    accepted: bool
    frames: tuple[int, ...]


def refine_shape(body: BodyModel, rig: Rig, alpha: np.ndarray, chis: np.ndarray, masks: list[np.ndarray],
                 frames: tuple[int, ...], settings: ShapeRefinement,
                 rng: np.random.Generator) -> ShapeResult:
    """Search the first ``settings.components`` coefficients of ``alpha`` and a shared shift on
    keyframes: poses chis (N, D), masks (N of (C, H, W) bool); frames: their indices (reported)."""
    C = min(settings.components, body.num_shape)
    scale = rig.scale_for(settings.resolution)
    alpha = np.asarray(alpha, np.float64)
    names = tuple(rig.names)
    coarse = [silhouette_target(m, scale, view_names=names) for m in masks]
    energy = shape_energy(body, rig.scaled(scale), chis, coarse, C, translate=True, alpha=alpha)
    x0 = np.r_[alpha[:C], np.zeros(3)]
    std = np.r_[np.full(C, settings.std), np.full(3, max(settings.shift, 1e-6) / 2)]
    limits = np.vstack([np.tile([-3.0, 3.0], (C, 1)), np.tile([-settings.shift, settings.shift], (3, 1))])
    apf = APFSettings(particles=settings.particles, layers=settings.layers, diffusion=0.7, shrink=0.9)
    x, _ = run_apf(energy, np.clip(x0, limits[:, 0], limits[:, 1]), std, limits, apf, rng)
    new = alpha.copy()
    new[:C] = x[:C]
    shift = x[C:]
    fine_scale = rig.scale_for(settings.check_resolution)
    fine = [silhouette_target(m, fine_scale, view_names=names) for m in masks]

    def check(a: np.ndarray, move: np.ndarray) -> float:
        sil = SilhouetteEnergy(body.shaped(a), rig, fine_scale)
        moved = np.stack([shifted(c, move) for c in chis])
        return float(np.mean([sil(c[None], t)[0] for c, t in zip(moved, fine, strict=True)]))

    before, after = check(alpha, np.zeros(3)), check(new, shift)
    accepted = bool(after < before * (1.0 - settings.min_gain))
    return ShapeResult(alpha=new if accepted else alpha, shift=shift if accepted else np.zeros(3),
                       energy_before=before, energy_after=after, accepted=accepted,
                       frames=tuple(int(f) for f in frames))


