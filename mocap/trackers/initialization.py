"""Shape and pose initialisation from multi-view silhouettes (Zhang et al. 2013, Sec. 3.1).

No ground truth is used. Starting from the mean body:
1. position: the 3D point closest to the rays through the silhouette centroids of all
   views (the body's centre), which places the pelvis above it on the floor;
2. heading: a coarse search over rotations about the vertical axis, scored by E_S;
3. hypotheses: silhouettes hardly tell front from back or the left limbs from the right ones,
   so the ``hypotheses`` best distinct headings and their opposites are each refined (an
   annealed search on E_S over all DOFs, then local optimisation on the contours), each
   result also with its limbs swapped left/right (:func:`mirror_map`); all are scored by E_S
   at ``select_resolution`` (finer than the search's, where feet, hands and the face decide)
   and the ``keep`` best go on;
3b. with ``limb_hypotheses`` > 0 and ``limb_stage`` "start", each kept hypothesis's limbs searched
   anew (:func:`scan_limbs`: a limb's angles drawn from a motion library, or uniformly, the best
   few searched over the limb, kept where the fine E_S falls): a forearm folded the wrong way or
   held in front of the torso lies far from the search's start in angle, not in E_S; with
   ``limb_stage`` "end", the winner's limbs after step 4 instead (the steps before draw the
   same numbers as without, so the start's fine E_S can only fall);
4. ``rounds`` of alternating refinement of each kept hypothesis: the pose (annealed search,
   local optimisation) and the shape coefficients (the first ``shape_components``, annealed
   search on E_S with the joint angles held fixed and, with ``shape_translate``, the body's
   position searched with them: a taller body on the same root would push its feet through
   the floor, so without it the search prefers a body of the mean height); the hypothesis of
   lowest fine E_S wins. After every round but the last, a kept hypothesis whose fine E_S is
   more than ``prune_margin`` (relative) above the best one's is dropped: where the margin is
   large the loser's remaining rounds are not spent.
6. with ``shape_pose_searches`` > 0, the winner's pose and first shape coefficients searched
   together (:mod:`mocap.trackers.start_shape`: where the silhouettes want another shape with
   another pose, the alternating rounds move neither), kept where the fine E_S falls; it draws
   from a copy of the generator, so what follows the start draws the same numbers as without.
The pose searches (heading search aside) score E_S on the energy mesh (``energy_mesh``
triangles, :mod:`mocap.body.energy_mesh`, as the silhouette APFs do); the shape searches and
the fine E_S that ranks hypotheses keep the full mesh (the shape changes the whole surface,
and the ranking is where feet, hands and the face decide). What does not change between
hypotheses is built once: the downscaled masks and their distance transforms (coarse and
fine), the observed contours, the contour matcher, and one energy per shape and resolution.
With ``coarse_layers`` / ``coarse_shape_layers`` > 0 (off by default: tried on dev as version 6,
not chosen, docs/results/speed.md) the pose / shape searches' first layers score a cheaper E_S
(``coarse_resolution`` px, ``coarse_mesh`` triangles; :func:`staged_energy`); with
``coarse_energy`` "points" (tried on dev as version 7, not chosen) that cheaper E_S is the point
chamfer of :mod:`mocap.energy.point_chamfer`: the ``coarse_mesh``'s vertices projected against the
search's own masks (no raster per particle).
``progress(stage, fraction)`` reports the searches done while it runs.
The diagnostics list every hypothesis with its energies, so a start that may have picked the
wrong one is visible (``margin``: the winner's lead over the runner-up, relative; over a dropped
hypothesis, its lead when that was dropped).
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np

from mocap.body.energy_mesh import energy_mesh_for
from mocap.body.model import BodyModel, ShapedBody
from mocap.body.twists import se3_log
from mocap.cameras import Rig, pixel_rays
from mocap.energy.point_chamfer import PointChamfer, PointChamferEnergy, point_weights
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.local.contour import ContourMatcher, observed_contours
from mocap.local.optimize import optimize_pose
from mocap.trackers.apf import run_apf
from mocap.trackers.shape_search import shape_energy, shifted  # noqa: F401  (shifted re-exported)
from mocap.trackers.start_shape import shape_pose_step
from mocap.trackers.tracker_settings import APFSettings, InitSettings

#: raised with every change of what :func:`initialize_from_silhouettes` computes from the same
#: inputs and settings: part of the initialisation cache's key (:mod:`mocap.trackers.init_cache`)
INITIALIZER_VERSION = 3      # raised when the initialiser's results change (cached poses are redone)


def closest_point_to_rays(origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Least-squares point nearest to rays (N, 3), (N, 3) unit."""
    P = np.eye(3)[None] - directions[:, :, None] * directions[:, None, :]
    return np.linalg.solve(P.sum(axis=0), (P @ origins[..., None]).sum(axis=0))[:, 0]


def silhouette_centre(rig: Rig, masks: np.ndarray) -> np.ndarray:
    """The point (3,) nearest to the rays through the centroids of the masks (C, H, W) that see
    the subject (at least 2 views, else a ValueError)."""
    origins, dirs = [], []
    for c, cam in enumerate(rig):
        ys, xs = np.nonzero(masks[c])
        if len(xs):
            o, d = pixel_rays(cam, np.array([[xs.mean(), ys.mean()]]))
            origins.append(o[0])
            dirs.append(d[0])
    if len(origins) < 2:
        raise ValueError("silhouette initialisation needs the subject in at least 2 views")
    return closest_point_to_rays(np.array(origins), np.array(dirs))


def root_twist(yaw: float, x: float, y: float) -> np.ndarray:
    """Global twist of a rotation about the vertical through the origin, then a shift in x, y."""
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = [x, y]
    return se3_log(T)


def mirror_map(body: BodyModel) -> tuple[np.ndarray, np.ndarray]:
    """Left/right swap of the joint angles: chi_swapped[6:] = sign * chi[6:][perm].

    Pairs ``l_*``/``r_*`` DOFs by name; the sign of each is found numerically, as the one for
    which the swapped pose of a body at the origin is the mirror image (x -> -x) of the pose.
    DOFs without a partner keep their value (sign +1; a midline twist is mirrored by -1 when
    that matches better)."""
    names = list(body.dof_names[6:])
    perm = np.arange(len(names))
    for i, n in enumerate(names):
        for a, b in (("l_", "r_"), ("r_", "l_")):
            if n.startswith(a) and b + n[2:] in names:
                perm[i] = names.index(b + n[2:])
    shaped = body.shaped()
    mirror = np.array([-1.0, 1.0, 1.0])
    sign = np.ones(len(names))
    rng = np.random.default_rng(0)
    theta = rng.uniform(0.2, 0.4, len(names))
    flip = [body.joint_names.index(("r_" if j.startswith("l_") else "l_") + j[2:])
            if j[:2] in ("l_", "r_") else k for k, j in enumerate(body.joint_names)]
    for i in range(len(names)):
        chi = np.zeros(body.num_dofs)
        chi[6 + i] = theta[i]
        want = shaped.joints(chi[None])[0] * mirror
        errs = []
        for s in (1.0, -1.0):
            c = np.zeros(body.num_dofs)
            c[6 + perm[i]] = s * theta[i]
            errs.append(np.abs(shaped.joints(c[None])[0][flip] - want).max())
        sign[perm[i]] = 1.0 if errs[0] <= errs[1] else -1.0
    return perm, sign


def dof_partitions(body: BodyModel) -> list[np.ndarray]:
    """Free-DOF masks (D,) for a partitioned search: the root with the midline DOFs (spine,
    neck), then each limb (DOFs of joints named l_/r_ with arm or leg words)."""
    D = body.num_dofs
    arm = ("clavicle", "shoulder", "elbow", "wrist")
    leg = ("hip", "knee", "ankle")
    masks = {"torso": np.zeros(D, bool)}
    masks["torso"][:6] = True
    for k, n in enumerate(body.dof_names[6:], start=6):
        side = n[:2] if n[:2] in ("l_", "r_") else ""
        part = ("arm" if any(w in n for w in arm) else "leg" if any(w in n for w in leg) else "")
        key = f"{side}{part}" if side and part else "torso"
        masks.setdefault(key, np.zeros(D, bool))[k] = True
    return [m for m in masks.values() if m.any()]


def limb_candidates(chi: np.ndarray, free: np.ndarray, count: int, limits: np.ndarray,
                    rng: np.random.Generator, library: np.ndarray | None = None) -> np.ndarray:
    """``count`` poses (count, D): ``chi`` (D,) with the ``free`` DOFs (D,) bool drawn anew, from
    rows of ``library`` (T, D; NaN: no value, drawn uniformly instead) where given, else
    uniformly within ``limits`` (D, 2); the other DOFs as in chi."""
    out = np.repeat(np.asarray(chi, np.float64)[None], count, axis=0)
    cols = np.flatnonzero(free)
    uniform = rng.uniform(limits[cols, 0], limits[cols, 1], (count, len(cols)))
    if library is not None and len(library):
        rows = library[rng.integers(len(library), size=count)][:, cols]
        uniform = np.where(np.isfinite(rows), rows, uniform)
    out[:, cols] = np.clip(uniform, limits[cols, 0], limits[cols, 1])
    return out


def scan_limbs(chi: np.ndarray, energy, fine_energy, limbs: list[np.ndarray], limits: np.ndarray,
               spread: np.ndarray, settings: InitSettings, rng: np.random.Generator,
               library: np.ndarray | None = None, root_point: np.ndarray | None = None
               ) -> tuple[np.ndarray, list[int]]:
    """Each limb of the pose chi (D,) searched anew, one after the other: its angles (the DOF mask
    ``limbs[k]`` (D,)) drawn ``settings.limb_hypotheses`` times (:func:`limb_candidates`), scored
    by ``energy`` ((P, D) -> (P,), the search's E_S); the ``settings.limb_keep`` best each
    searched over the limb's DOFs (an APF of ``limb_particles`` x ``limb_layers`` from first-layer
    spread ``spread`` (D,)); the lowest by ``fine_energy`` replaces the limb where it lowers the
    fine energy of the pose so far. Silhouettes of an arm in front of the torso, or a forearm
    folded the other way, lie far from the start in angle but near it in E_S: an annealed search
    from the start does not reach them, a draw of the whole limb does. Returns (pose, indices k
    of the limbs changed)."""
    apf = APFSettings(particles=settings.limb_particles, layers=settings.limb_layers, diffusion=0.7,
                      shrink=0.9)
    chi = np.asarray(chi, np.float64)
    best = float(fine_energy(chi[None])[0])
    changed = []
    for k, free in enumerate(limbs):
        cands = limb_candidates(chi, free, settings.limb_hypotheses, limits, rng, library)
        e = energy(cands)
        tried = []
        for i in np.argsort(e)[:settings.limb_keep]:
            found, _ = run_apf(energy, cands[i], spread, limits, apf, rng, free=free, root_point=root_point)
            tried.append((float(fine_energy(found[None])[0]), found))
        e_best, found = min(tried, key=lambda t: t[0])
        if e_best < best:
            best, chi = e_best, found
            changed.append(k)
    return chi, changed


def staged_energy(coarse: Callable[[np.ndarray], np.ndarray], fine: Callable[[np.ndarray], np.ndarray],
                  layers: int, coarse_layers: int) -> Callable[[np.ndarray], np.ndarray]:
    """An energy (P, D) -> (P,) for one annealed search of ``layers`` layers: its first
    ``coarse_layers`` calls answered by ``coarse``, the others by ``fine`` (the search calls
    its energy once per layer, so call k scores layer k mod layers). The early layers spread
    the particles wide and only their ranking matters (the weights are normalised by the
    layer's energy spread); the last layers, which place the estimate, see the search's own
    energy."""
    calls = [0]

    def energy(x: np.ndarray) -> np.ndarray:
        m = calls[0] % layers
        calls[0] += 1
        return coarse(x) if m < coarse_layers else fine(x)

    return energy


def swap_limbs(chi: np.ndarray, perm: np.ndarray, sign: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """The pose with its left and right joint angles exchanged (root unchanged), in the limits."""
    out = np.asarray(chi, np.float64).copy()
    out[6:] = sign * chi[6:][perm]
    return np.clip(out, limits[:, 0], limits[:, 1])


class _Progress:
    """(stage, fraction) reports of the work done, in units of planned searches (one more unit
    for the end, so that only :meth:`finish` reports 1.0)."""

    def __init__(self, callback: Callable[[str, float], None] | None, total: float):
        self.callback, self.total, self.done = callback, float(total) + 1.0, 0.0

    def __call__(self, stage: str, units: float = 0.0) -> None:
        self.done = min(self.done + units, self.total - 1.0)
        if self.callback is not None:
            self.callback(stage, self.done / self.total)

    def drop(self, units: float) -> None:
        """Planned work that will not run (a pruned hypothesis)."""
        self.total = max(self.total - units, self.done + 1.0)

    def finish(self) -> None:
        self.done = self.total
        if self.callback is not None:
            self.callback("done", 1.0)


def initialize_from_silhouettes(body: BodyModel, rig: Rig, masks: np.ndarray, rng: np.random.Generator,
                                settings: InitSettings = InitSettings(),  # noqa: B008 (frozen)
                                progress: Callable[[str, float], None] | None = None,
                                library: np.ndarray | None = None
                                ) -> tuple[np.ndarray, np.ndarray, dict]:
    """(chi (D,), alpha (K,), diagnostics) estimated from one frame's masks (C, H, W).

    library: poses (T, D) (NaN: no value) the limb hypotheses (``limb_hypotheses`` > 0) draw a
    limb's angles from; None: uniformly within the joint limits.

    progress: called as ``progress(stage, fraction)`` while it runs (stages "heading",
    "hypotheses", "refine", "done"; fractions non-decreasing, the last call
    ("done", 1.0) and no other at 1.0). The results do not depend on it."""
    if masks is None:
        raise ValueError("silhouette initialisation needs masks")
    if settings.search != "anneal":
        raise ValueError(f"setting search = {settings.search!r}: this is the annealed start; the "
                         "retrieval start is mocap.trackers.init_retrieval.initialize_by_retrieval")
    scale = rig.scale_for(settings.resolution)
    target = silhouette_target(masks, scale, view_names=tuple(rig.names))
    small = rig.scaled(scale)
    # 1. position from the silhouette centroids
    center = silhouette_centre(rig, masks)
    alpha = np.zeros(body.num_shape)
    mesh = energy_mesh_for(body, settings.energy_mesh)     # None: the full mesh
    # built once, shared by every hypothesis: shaped bodies and energies per shape (and scale)
    shapes: dict[bytes, ShapedBody] = {}
    energies: dict[tuple, SilhouetteEnergy] = {}

    def shaped_for(a: np.ndarray) -> ShapedBody:
        key = np.asarray(a, np.float64).tobytes()
        if key not in shapes:
            shapes[key] = body.shaped(a)
        return shapes[key]

    def energy_for(a: np.ndarray, at: float, coarse: bool, on=None) -> SilhouetteEnergy:
        """E_S of shape a at scale ``at``: on the energy mesh (coarse) or the full one, or on
        the mesh ``on`` where given."""
        on = (mesh if coarse else None) if on is None else on
        key = (np.asarray(a, np.float64).tobytes(), at, id(on))
        if key not in energies:
            energies[key] = SilhouetteEnergy(shaped_for(a), rig, at, mesh=on)
        return energies[key]

    # 2. heading search with the mean body in the rest pose (full mesh: 12 poses)
    sil = energy_for(alpha, scale, False)
    yaws = np.linspace(0, 2 * np.pi, settings.headings, endpoint=False)
    cands = np.zeros((len(yaws), body.num_dofs))
    for i, yaw in enumerate(yaws):
        cands[i, :6] = root_twist(yaw, center[0], center[1])
    e_head = sil(cands, target)
    diag = {"center": center.tolist(), "heading_energy": e_head.tolist()}
    std = np.r_[np.full(3, 0.05), np.full(3, 0.15), np.full(body.num_dofs - 6, 0.3)]
    obs = observed_contours(masks)
    matcher = ContourMatcher(body, rig)
    apf = APFSettings(particles=settings.pose_particles, layers=settings.pose_layers, diffusion=0.7,
                      shrink=0.9)
    fine_scale = rig.scale_for(settings.select_resolution)
    fine_target = silhouette_target(masks, fine_scale, view_names=tuple(rig.names))

    def fine_energy(a: np.ndarray, chi: np.ndarray) -> float:
        return float(energy_for(a, fine_scale, False)(chi[None], fine_target)[0])

    groups = dof_partitions(body) if settings.partitioned else []

    limbs = dof_partitions(body)[1:]            # the torso's partition first, then the limbs

    def limb_scan(a: np.ndarray, chi: np.ndarray, hyp: dict) -> np.ndarray:
        sil, fine = energy_for(a, scale, True), energy_for(a, fine_scale, False)
        chi, hyp["limbs_changed"] = scan_limbs(
            chi, lambda x: sil(x, target), lambda x: fine(x, fine_target), limbs, body.limits,
            std * 0.5, settings, rng, library, root_point=sil.shaped.rest_joints[0])
        return chi

    # version 6: the pose searches' first coarse_layers layers on a cheaper E_S (coarser masks,
    # a coarser mesh), built once like the others
    early, early_shape = settings.coarse_layers, settings.coarse_shape_layers
    points = settings.coarse_energy == "points"
    if early or early_shape:
        early_mesh = energy_mesh_for(body, settings.coarse_mesh)
        if points:      # version 7: the point chamfer needs no coarser masks: the search's own
            early_scale, early_target, early_small = scale, target, small
        else:
            early_scale = rig.scale_for(settings.coarse_resolution)
            early_target = silhouette_target(masks, early_scale, view_names=tuple(rig.names))
            early_small = rig.scaled(early_scale)
    point_energies: dict[bytes, PointChamferEnergy] = {}

    def cheap_for(a: np.ndarray):
        """the early layers' E_S of shape a: the coarse raster, or the point chamfer"""
        if not points:
            return energy_for(a, early_scale, False, on=early_mesh)
        key = np.asarray(a, np.float64).tobytes()
        if key not in point_energies:
            point_energies[key] = PointChamferEnergy(shaped_for(a), rig, scale, mesh=early_mesh,
                                                     samples=settings.coarse_samples)
        return point_energies[key]

    def refine_pose(a: np.ndarray, chi: np.ndarray, spread: np.ndarray) -> np.ndarray:
        sil = energy_for(a, scale, True)          # the energy mesh
        if early:
            cheap = cheap_for(a)

        def search(x0, free=None):
            energy = lambda x: sil(x, target)                                      # noqa: E731
            if early:
                energy = staged_energy(lambda x: cheap(x, early_target), energy, apf.layers, early)
            return run_apf(energy, x0, spread, body.limits, apf, rng, free=free,
                           root_point=sil.shaped.rest_joints[0])[0]

        for free in groups:                       # partitioned: torso first, then each limb
            chi = search(chi, free)
        return local(a, search(chi))

    def local(a: np.ndarray, chi: np.ndarray) -> np.ndarray:
        chi, _ = optimize_pose(shaped_for(a), chi, lambda v: matcher(v, obs), settings.local_iterations)
        return chi

    # 3. hypotheses: distinct headings, their opposites, each with its limbs swapped
    order = np.argsort(e_head)
    picked: list[float] = []
    for i in order:        # distinct up to +180 deg (the opposite is a hypothesis of its own)
        gap = [abs((yaws[i] - y + np.pi / 2) % np.pi - np.pi / 2) for y in picked]
        if all(g > np.pi / 3 + 1e-9 for g in gap):
            picked.append(float(yaws[i]))
        if len(picked) == max(1, settings.hypotheses):
            break
    # hypotheses=0: a single hypothesis (the best heading as found), for comparison
    headings = picked if settings.hypotheses == 0 else [y + d for y in picked for d in (0.0, np.pi)]
    perm, sign = mirror_map(body)
    hypotheses = []
    keep = min(max(1, settings.keep), len(headings) * (2 if settings.hypotheses > 0 else 1))
    # 20-70 s on a real recording: the searches (headings, then rounds per hypothesis) reported
    report = _Progress(progress, len(headings) + settings.rounds * keep + keep)
    report("heading", 0.0)
    for yaw in headings:
        h = np.zeros(body.num_dofs)
        h[:6] = root_twist(yaw, center[0], center[1])
        h = refine_pose(alpha, h, std)
        variants = [("refined", h)]
        if settings.hypotheses > 0:
            variants.append(("limbs swapped", local(alpha, swap_limbs(h, perm, sign, body.limits))))
        for kind, v in variants:
            hypotheses.append({"heading_deg": float(np.degrees(yaw) % 360), "kind": kind,
                               "energy": fine_energy(alpha, v), "chi": v})
        report("hypotheses", 1.0)
    hypotheses.sort(key=lambda d: d["energy"])
    kept = hypotheses[:max(1, settings.keep)]
    C, move = settings.shape_components, float(settings.shape_translate)
    shape_std = np.full(C, 0.8)
    shape_limits = np.tile([-3.0, 3.0], (C, 1))
    # the body's position searched with its shape (std a third of the range)
    move_std = np.r_[shape_std, np.full(3, move / 3)]
    move_limits = np.vstack([shape_limits, np.tile([-move, move], (3, 1))])
    shape_apf = APFSettings(particles=settings.shape_particles, layers=settings.shape_layers,
                            diffusion=0.7, shrink=0.9)
    if settings.limb_hypotheses > 0 and settings.limb_stage == "start":   # 3b. limbs searched anew
        for hyp in kept:
            hyp["chi"] = limb_scan(alpha, hyp["chi"], hyp)
    state = [[hyp, hyp["chi"], alpha.copy()] for hyp in kept]     # hypothesis, pose, shape
    alive = list(range(len(state)))
    for r in range(settings.rounds):          # round by round, so that losers can be dropped
        for i in alive:
            hyp, chi, a = state[i]
            # 4a. pose: annealed search on E_S, then local optimisation on the contours
            chi = refine_pose(a, chi, std * (0.5 ** (r + 1)))
            # 4b. shape: annealed search over the first components, pose fixed; with
            # shape_translate also one that moves the body, the lower E_S of the two kept
            # (the larger search loses a little where the mean height was right)
            energy = shape_energy(body, small, chi, target, C, translate=True, compiled=True)
            # version 7's points: weighted by the areas of the hypothesis's shape (each particle's
            # own shape moves them little)
            point_kernel = (PointChamfer(point_weights(shaped_for(a), early_mesh), settings.coarse_samples)
                            if points and early_shape else None)
            cheap = (shape_energy(body, early_small, chi, early_target, C, translate=True, compiled=True,
                                  mesh=early_mesh, kernel=point_kernel) if early_shape else None)

            def searched(e=energy, cheap=cheap):
                """the search's energy; version 6: its first layers at the coarse resolution"""
                return e if cheap is None else staged_energy(cheap, e, shape_apf.layers, early_shape)
            e_c = searched()
            c, _ = run_apf(lambda x, e=e_c: e(np.c_[x, np.zeros((len(x), 3))]), a[:C],
                           shape_std * (0.6**r), shape_limits, shape_apf, rng)
            c = np.r_[c, np.zeros(3)]
            if move > 0:
                m, _ = run_apf(searched(), np.r_[a[:C], np.zeros(3)], move_std * (0.6**r), move_limits,
                               shape_apf, rng)
                if energy(m[None])[0] < energy(c[None])[0]:
                    c = m
                hyp.setdefault("shape_shift_m", []).append([round(float(x), 4) for x in c[C:]])
            a = a.copy()
            a[:C] = c[:C]
            chi = shifted(chi, c[C:]) if move > 0 else chi
            state[i][1:] = [chi, a]
            report("refine", 1.0)
        if len(alive) > 1 and r < settings.rounds - 1:
            for i in alive:
                state[i][0].setdefault("round_energy", []).append(fine_energy(state[i][2], state[i][1]))
            if settings.prune_margin is not None:
                best = min(state[i][0]["round_energy"][-1] for i in alive)
                lead = {i: (state[i][0]["round_energy"][-1] - best) / max(best, 1e-12) for i in alive}
                for i in alive:
                    if lead[i] > settings.prune_margin:
                        state[i][0]["pruned_after_round"] = r + 1
                        state[i][0]["lead_when_pruned"] = lead[i]
                dropped = sum(lead[i] > settings.prune_margin for i in alive)
                alive = [i for i in alive if lead[i] <= settings.prune_margin]
                report.drop(dropped * (settings.rounds - r))      # their later rounds and final search
    finals = []
    for i, (hyp, chi, a) in enumerate(state):
        if i in alive:
            chi = local(a, chi)
            hyp["final_energy"] = fine_energy(a, chi)
            finals.append((hyp["final_energy"], chi, a))
            report("refine", 1.0)
        else:                                  # dropped: its energy when it was dropped
            hyp["final_energy"] = hyp["round_energy"][-1]
    finals.sort(key=lambda t: t[0])
    _, chi, alpha = finals[0]
    if settings.limb_hypotheses > 0 and settings.limb_stage == "end":     # 5. the winner's limbs anew
        winner = {}
        chi = limb_scan(alpha, chi, winner)
        diag["limbs_changed_at_end"] = winner["limbs_changed"]
    if settings.shape_pose_searches > 0:      # 6. the shape searched with the pose (a copy of the
        chi, alpha, diag["shape_pose"] = shape_pose_step(     # generator: the tracking's draws unchanged)
            body, small, target, None, fine_energy, local, chi, alpha, settings, std, copy.deepcopy(rng))
    report.finish()
    diag["hypotheses"] = [{k: v for k, v in h.items() if k != "chi"} for h in hypotheses]
    # the winner's lead: over the runner-up at the end, or over a dropped one when it was dropped
    leads = [(e - finals[0][0]) / max(finals[0][0], 1e-12) for e, _, _ in finals[1:]]
    leads += [state[i][0]["lead_when_pruned"] for i in range(len(state)) if i not in alive]
    diag["margin"] = float(min(leads)) if leads else None
    return chi, alpha, diag
