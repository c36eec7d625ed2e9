"""The silhouette start by retrieval (``InitSettings.search = "retrieval"``, issue 38 item 2): a
search whose cost does not grow with annealing layers. Tried on the dev split and NOT chosen
(docs/results/speed.md, "Initialiser, version 5 tried"): off by default.

1. position: the point nearest to the rays through the silhouettes' centroids
   (:func:`mocap.trackers.initialization.silhouette_centre`);
2. retrieval: every pose of a motion library (the procedural pose prior's training poses and
   their mirror images, :func:`library_of`, the hybrid's restart library; the rest pose with
   them) at each of ``retrieval_headings`` headings about the vertical, all scored in batches by
   E_S at ``retrieval_resolution`` on the energy mesh: one set of coarse evaluations shared by
   every heading hypothesis;
3. each heading's best pose has its root searched once (:func:`coordinate_search` on the root:
   small moves, turns about the vertical, trunk leans with the legs held, :func:`leaned`); the
   ``retrieval_keep`` best headings more than 60 deg apart (:func:`distinct_best`) are each
   searched over every partition (``retrieval_sweeps`` sweeps; on the first, each limb's batch
   also holds the library's angles for it and ``retrieval_draws`` uniform draws), then the
   contour step (kept only where it lowers the fine E_S), and ranked by the fine E_S
   (``select_resolution``, full mesh);
4. the ``keep`` best: the shape (pose held, with the body's shift; an APF of ``shape_particles``
   x ``shape_layers``), the coordinate search again at ``resolution`` with that shape, the
   contour step, the shape once more, the contour step; the lowest fine E_S wins;
5. with ``limb_hypotheses`` > 0 (the hybrid presets), the winner's limbs searched anew
   (:func:`mocap.trackers.initialization.scan_limbs`), as version 3 does with ``limb_stage`` "end".

:func:`coordinate_search` is a greedy batch search: per partition a batch of proposals around
the best pose so far, the best taken where it lowers E_S (no annealing weights, no resampling).
Cost in silhouette evaluations: L x H for the retrieval, about 30 x H for the root searches,
then per candidate ``retrieval_sweeps`` x (5 x ``retrieval_samples`` + 14 root moves) + 4 x (L +
``retrieval_draws``), independent of any layer count.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mocap.body.energy_mesh import energy_mesh_for
from mocap.body.model import BodyModel
from mocap.body.root_motion import perturb_root
from mocap.body.twists import se3_exp
from mocap.cameras import Rig
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.local.contour import ContourMatcher, observed_contours
from mocap.local.optimize import optimize_pose
from mocap.trackers.apf import perturb, run_apf
from mocap.trackers.initialization import (
    _Progress,
    dof_partitions,
    mirror_map,
    root_twist,
    scan_limbs,
    silhouette_centre,
)
from mocap.trackers.shape_search import shape_energy, shifted
from mocap.trackers.tracker_settings import APFSettings, InitSettings


def library_of(body: BodyModel) -> np.ndarray:
    """The motion library (T, D) of the body's procedural pose prior (its training poses, the
    hybrid's restart library), each pose also with its limbs swapped (2T rows; NaN: no value)."""
    from mocap.energy.prior import ParzenPrior, default_prior_path

    lib = ParzenPrior.load(default_prior_path(body.name))
    rows = np.full((len(lib.samples), body.num_dofs), np.nan)
    for i, n in enumerate(lib.dof_names):
        if n in body.dof_names:
            rows[:, body.dof_index(n)] = lib.samples[:, i]
    perm, sign = mirror_map(body)
    swapped = rows.copy()
    swapped[:, 6:] = sign * rows[:, 6:][:, perm]
    return np.vstack([rows, swapped])


def joint_rows(library: np.ndarray | None, limits: np.ndarray) -> np.ndarray:
    """The joint angles (L, D - 6) to retrieve from: the rest pose, then the library's rows (T, D)
    with NaN read as the rest angle (0), clipped to the limits (D, 2); duplicates dropped."""
    D = len(limits)
    rows = np.zeros((1, D - 6))
    if library is not None and len(library):
        lib = np.nan_to_num(np.asarray(library, np.float64)[:, 6:], nan=0.0)
        rows = np.vstack([rows, np.clip(lib, limits[6:, 0], limits[6:, 1])])
    _, first = np.unique(rows, axis=0, return_index=True)
    return rows[np.sort(first)]


def retrieval_candidates(joints: np.ndarray, yaws: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Every joint-angle row (L, D - 6) at every heading (H,): poses (H * L, D), heading-major,
    the root turned by each yaw about the vertical through ``centre`` (3,) (its x, y)."""
    L, H = len(joints), len(yaws)
    out = np.zeros((H * L, joints.shape[1] + 6))
    for h, yaw in enumerate(yaws):
        out[h * L:(h + 1) * L, :6] = root_twist(yaw, centre[0], centre[1])
        out[h * L:(h + 1) * L, 6:] = joints
    return out


def distinct_best(energies: np.ndarray, yaws: np.ndarray, joints: np.ndarray, count: int,
                  heading_gap: float, pose_gap: float) -> list[int]:
    """Indices into the heading-major candidates (H * L,) of the ``count`` lowest ``energies``
    that differ pairwise: by more than ``heading_gap`` (rad) in heading, or by more than
    ``pose_gap`` (rad, RMS over the joint angles (L, D - 6)) in pose."""
    L = len(joints)
    picked: list[int] = []
    for i in np.argsort(energies, kind="stable"):
        h, p = divmod(int(i), L)
        close = False
        for j in picked:
            hj, pj = divmod(j, L)
            turn = abs((yaws[h] - yaws[hj] + np.pi) % (2 * np.pi) - np.pi)
            rms = float(np.sqrt(np.mean((joints[p] - joints[pj]) ** 2)))
            if turn <= heading_gap and rms <= pose_gap:
                close = True
                break
        if not close:
            picked.append(int(i))
        if len(picked) == count:
            break
    return picked


#: the turns about the vertical tried on each sweep of the root's partition (rad, times the
#: sweep's shrink): the retrieval's headings are 30 deg apart
TURNS = np.array([-0.5, -0.25, 0.25, 0.5])
#: the leans tried on each sweep of the root's partition (rad, times the sweep's shrink)
LEANS = np.array([-1.0, -0.8, -0.6, -0.4, -0.2, 0.2, 0.4, 0.6, 0.8, 1.0])


def lean_of(shaped) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """The trunk's lean with the legs held, for a body without spine DOFs (a bow): (axis (3,) in
    the rest frame: the first hip-flexion DOF's, centre (3,): the mean rest position of the hips,
    hip-flexion DOF indices (k,), their signs (k,)); None without DOFs named ``*hip_flex``."""
    names = list(shaped.model.dof_names)
    hips = np.array([i for i, n in enumerate(names) if n.endswith("hip_flex")], int)
    if not len(hips):
        return None
    axes = np.asarray(shaped.axes, np.float64)[hips - 6]          # (D - 6, 3): the joint DOFs'
    u = axes[0] / np.linalg.norm(axes[0])
    centre = np.asarray(shaped.rest_joints, np.float64)[shaped.model.dof_joint[hips - 6]].mean(axis=0)
    return u, centre, hips, -(axes @ u)


def leaned(chi: np.ndarray, angles: np.ndarray, lean, limits: np.ndarray) -> np.ndarray:
    """Poses (n, D): chi (D,) with the body turned by each of ``angles`` (n,) rad about the lean
    axis through the hips (:func:`lean_of`), the hips flexed back by as much (the legs stay)."""
    u, centre, hips, signs = lean
    R = se3_exp(np.asarray(chi[None, :6], np.float64))[0, :3, :3]
    noise = np.zeros((len(angles), 6))
    noise[:, 3:] = angles[:, None] * (R @ u)
    out = np.repeat(np.asarray(chi, np.float64)[None], len(angles), axis=0)
    out[:, :6] = perturb_root(out[:, :6], noise, centre)
    out[:, hips] += angles[:, None] * signs
    return np.clip(out, limits[:, 0], limits[:, 1])


def coordinate_search(energy: Callable[[np.ndarray], np.ndarray], chi: np.ndarray, parts: list[np.ndarray],
                      std: np.ndarray, limits: np.ndarray, rng: np.random.Generator, samples: int,
                      sweeps: int, shrink: float = 0.5, library: np.ndarray | None = None,
                      draws: int = 0, root_point: np.ndarray | None = None,
                      lean=None) -> tuple[np.ndarray, float]:
    """A pose (D,) of lower ``energy`` ((P, D) -> (P,)) near ``chi`` (D,): ``sweeps`` passes over
    the DOF masks ``parts`` (each (D,) bool), each pass one batch per part: ``samples`` Gaussian
    proposals (std ``std`` (D,) on the part's DOFs, times ``shrink`` per sweep; the root turned
    about ``root_point`` (3,) as the APF's diffusion does) and, on the first sweep, the part's
    angles of each pose of ``library`` (L, D; joint DOFs only, no NaN) and ``draws`` angles drawn
    uniformly within the limits (D, 2); the best of a batch replaces the pose where its energy is
    lower. The root's batches also hold the pose turned about the vertical through the root by
    :data:`TURNS` and, with ``lean`` (:func:`lean_of`), leaned by :data:`LEANS` with the legs held
    (both times the sweep's shrink). Returns (pose (D,), its energy)."""
    chi = np.asarray(chi, np.float64)
    best = float(energy(chi[None])[0])
    for s in range(sweeps):
        for free in parts:
            step = np.where(free, std * shrink**s, 0.0)
            batch = perturb(np.repeat(chi[None], samples, axis=0), step, limits, rng, root_point)
            if s == 0 and not free[:6].any():
                lib = library[:, free] if library is not None else np.zeros((0, free.sum()))
                drawn = rng.uniform(limits[free, 0], limits[free, 1], (draws, free.sum()))
                rows = np.repeat(chi[None], len(lib) + draws, axis=0)
                rows[:, free] = np.vstack([lib, drawn])
                batch = np.vstack([batch, rows])
            if free[:6].any() and root_point is not None:      # turns about the vertical
                turn = np.zeros((len(TURNS), 6))
                turn[:, 5] = TURNS * shrink**s
                turned = np.repeat(chi[None], len(TURNS), axis=0)
                turned[:, :6] = perturb_root(turned[:, :6], turn, root_point)
                batch = np.vstack([batch, turned])
                if lean is not None:                              # each turn also leaned
                    batch = np.vstack([batch, *(leaned(t, LEANS * shrink**s, lean, limits) for t in turned)])
            if lean is not None and free[:6].any():
                batch = np.vstack([batch, leaned(chi, LEANS * shrink**s, lean, limits)])
            e = energy(batch)
            i = int(np.argmin(e))
            if e[i] < best:
                best, chi = float(e[i]), batch[i].copy()
    return chi, best


def initialize_by_retrieval(body: BodyModel, rig: Rig, masks: np.ndarray, rng: np.random.Generator,
                            settings: InitSettings, progress: Callable[[str, float], None] | None = None,
                            library: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """(chi (D,), alpha (K,), diagnostics) from one frame's masks (C, H, W), as
    :func:`mocap.trackers.initialization.initialize_from_silhouettes` returns them (the module
    docstring says how). library: poses (T, D) (NaN: no value) to retrieve from; None: the
    body's procedural prior's (:func:`library_of`)."""
    centre = silhouette_centre(rig, masks)
    names = tuple(rig.names)
    alpha = np.zeros(body.num_shape)
    shaped = body.shaped(alpha)
    mesh = energy_mesh_for(body, settings.energy_mesh)
    coarse_scale = rig.scale_for(settings.retrieval_resolution)
    scale = rig.scale_for(settings.resolution)
    fine_scale = rig.scale_for(settings.select_resolution)
    coarse_target = silhouette_target(masks, coarse_scale, view_names=names)
    target = silhouette_target(masks, scale, view_names=names)
    fine_target = silhouette_target(masks, fine_scale, view_names=names)
    limits = body.limits
    root_point = shaped.rest_joints[0]
    report = _Progress(progress, 2 + settings.retrieval_keep + settings.keep)

    def fine(a_shaped, chi: np.ndarray) -> float:
        return float(SilhouetteEnergy(a_shaped, rig, fine_scale)(chi[None], fine_target)[0])

    obs = observed_contours(masks)
    matcher = ContourMatcher(body, rig)

    def local(a_shaped, chi: np.ndarray) -> tuple[np.ndarray, float]:
        """The contour step, kept where it lowers the fine E_S (from a pose far off it can raise
        it); (pose, its fine E_S)."""
        moved = optimize_pose(a_shaped, chi, lambda v: matcher(v, obs), settings.local_iterations)[0]
        e0, e1 = fine(a_shaped, chi), fine(a_shaped, moved)
        return (moved, e1) if e1 < e0 else (chi, e0)

    # 2. retrieval: every library pose at every heading, one batch of coarse evaluations
    report("retrieval", 0.0)
    lib = library_of(body) if library is None else library
    joints = joint_rows(lib, limits)
    yaws = np.linspace(0, 2 * np.pi, settings.retrieval_headings, endpoint=False)
    cands = retrieval_candidates(joints, yaws, centre)
    coarse = SilhouetteEnergy(shaped, rig, coarse_scale, mesh=mesh)
    e = np.concatenate([coarse(c, coarse_target) for c in np.array_split(cands, max(1, len(cands) // 512))])
    report("retrieval", 1.0)
    parts = dof_partitions(body)
    std = np.r_[np.full(3, 0.05), np.full(3, 0.15), np.full(body.num_dofs - 6, 0.3)]
    # each heading's best pose, its root searched once (turns, leans, small moves); then the best
    # headings more than 60 deg apart (the limbs' search hardly moves the heading)
    L = len(joints)
    best_rows = [h * L + int(np.argmin(e[h * L:(h + 1) * L])) for h in range(len(yaws))]
    lean = lean_of(shaped)
    rooted = [coordinate_search(lambda x: coarse(x, coarse_target), cands[i], parts[:1], std, limits, rng,
                                settings.retrieval_samples // 2, 1, root_point=root_point, lean=lean)
              for i in best_rows]
    e_root = np.array([r[1] for r in rooted])
    picked = [best_rows[h] for h in distinct_best(e_root, yaws, np.zeros((1, 1)), settings.retrieval_keep,
                                                  np.pi / 3 + 1e-9, np.inf)]
    start = {i: r[0] for i, r in zip(best_rows, rooted, strict=True)}
    lib_rows = np.repeat(cands[:1], len(joints), axis=0)
    lib_rows[:, 6:] = joints
    C, move = settings.shape_components, float(settings.shape_translate)
    x_std = np.r_[np.full(C, 0.8), np.full(3, move / 3)]
    x_limits = np.vstack([np.tile([-3.0, 3.0], (C, 1)), np.tile([-move, move], (3, 1))])
    shape_apf = APFSettings(particles=settings.shape_particles, layers=settings.shape_layers,
                            diffusion=0.7, shrink=0.9)
    at = {coarse_scale: (rig.scaled(coarse_scale), coarse_target), scale: (rig.scaled(scale), target)}

    def shape(chi: np.ndarray, a: np.ndarray, spread: float, res: float) -> tuple[np.ndarray, np.ndarray]:
        """The first C shape coefficients and the body's shift searched, the pose held."""
        small, tgt = at[res]
        energy = shape_energy(body, small, chi, tgt, C, translate=True, alpha=a, compiled=True)
        x, _ = run_apf(energy, np.r_[a[:C], np.zeros(3)], x_std * spread, x_limits, shape_apf, rng)
        a = a.copy()
        a[:C] = x[:C]
        return shifted(chi, x[C:]), a

    def pose(chi: np.ndarray, a: np.ndarray, res: float, spread: float, sweeps: int, draws: bool):
        """The coordinate search with the shape a at resolution res (draws: the limbs anew)."""
        a_shaped = body.shaped(a)
        sil, tgt = SilhouetteEnergy(a_shaped, rig, res, mesh=mesh), at[res][1]
        return coordinate_search(lambda x: sil(x, tgt), chi, parts, std * spread, limits, rng,
                                 settings.retrieval_samples, sweeps, library=lib_rows if draws else None,
                                 draws=settings.retrieval_draws if draws else 0,
                                 root_point=a_shaped.rest_joints[0], lean=lean_of(a_shaped))[0]

    hypotheses = []
    for i in picked:      # 3. each: the shape, the limbs anew and two sweeps with it, the contours
        a = alpha
        chi = pose(start[i], a, coarse_scale, 1.0, settings.retrieval_sweeps, True)
        chi, e_fine = local(body.shaped(a), chi)
        h, p = divmod(i, len(joints))
        hypotheses.append({"heading_deg": float(np.degrees(yaws[h])), "library_row": int(p),
                           "retrieval_energy": float(e[i]), "energy": e_fine, "chi": chi, "alpha": a})
        report("hypotheses", 1.0)
    hypotheses.sort(key=lambda d: d["energy"])
    # 4. the best few: the shape again, sweeps at the finer resolution, the contours, the shape
    # once more; the lowest fine E_S wins
    finals = []
    for hyp in hypotheses[:max(1, settings.keep)]:
        chi, a = shape(hyp["chi"], hyp.pop("alpha"), 1.0, scale)
        chi = pose(chi, a, scale, 0.5, settings.retrieval_sweeps, False)
        chi, hyp["searched_energy"] = local(body.shaped(a), chi)
        chi, a = shape(chi, a, 0.4, scale)
        chi, hyp["final_energy"] = local(body.shaped(a), chi)
        finals.append((hyp["final_energy"], chi, a))
        report("refine", 1.0)
    finals.sort(key=lambda t: t[0])
    _, chi, alpha = finals[0]
    diag = {}
    if settings.limb_hypotheses > 0:          # the limb hypotheses (the hybrid's): the winner's limbs
        a_shaped = body.shaped(alpha)
        sil = SilhouetteEnergy(a_shaped, rig, scale, mesh=mesh)
        fine_e = SilhouetteEnergy(a_shaped, rig, fine_scale)
        chi, diag["limbs_changed_at_end"] = scan_limbs(
            chi, lambda x: sil(x, target), lambda x: fine_e(x, fine_target), parts[1:], limits, std * 0.5,
            settings, rng, library, root_point=a_shaped.rest_joints[0])
    report.finish()
    leads = [(f - finals[0][0]) / max(finals[0][0], 1e-12) for f, _, _ in finals[1:]]
    diag |= {"center": centre.tolist(), "search": "retrieval", "retrieved": len(cands),
             "hypotheses": [{k: v for k, v in h.items() if k not in ("chi", "alpha")} for h in hypotheses],
             "margin": float(min(leads)) if leads else None}
    return chi, alpha, diag
