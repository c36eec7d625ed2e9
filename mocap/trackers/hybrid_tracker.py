"""The hybrid tracker (``hybrid``), the full system of Zhang et al. 2013: local optimisation
every frame; when a limb is misaligned afterwards, the prior-constrained annealed particle
filter searches the degrees of freedom of the misaligned limbs only (the others held at the
local result), and a short local refinement follows. The searched pose replaces the local one
only where it lowers the frame's silhouette energy E_S, so the fallback cannot make a frame
worse by the measure the tracker is judged on (``Misalignment.apf_accepted``). With
``patrol`` = N, every N-th frame on which nothing was flagged one limb chain in turn is
searched all the same (``Misalignment.patrol``).

With ``keypoints.weight`` > 0 (``hybrid_kp``) the frame's 2D keypoint detections are a second
cue (:mod:`mocap.trackers.keypoint_cue`): correspondences in the local optimiser, the marker
likelihood beside E_S in the search and its acceptance test, a limb test in the
misalignment check, and a search of every limb chain refining the self-initialisation's pose
(:meth:`HybridTracker.refine_initial`)."""

from __future__ import annotations

import copy
import dataclasses
import time

import numpy as np

from mocap.body.energy_mesh import energy_mesh_for
from mocap.body.model import BodyModel
from mocap.body.skeleton import fit_joint_offsets
from mocap.body.twists import se3_exp, se3_log
from mocap.cameras import Rig
from mocap.energy.prior import PosePrior
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.energy.smoothness import predict_constant_velocity
from mocap.energy.total import FrameEnergy
from mocap.local.misalignment import LimbCheck, limb_chains
from mocap.trackers.apf import anneal, perturb
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.contract import SearchBudget, initial_estimate_of
from mocap.trackers.diagnostics import Misalignment, StepDiagnostics
from mocap.trackers.heading import chains_flagged, flagged_chains, turned_by
from mocap.trackers.initialization import mirror_map, swap_limbs
from mocap.trackers.joint_limits import tracker_body
from mocap.trackers.keypoint_cue import KeypointCue, check_detections
from mocap.trackers.local_tracker import LocalTracker
from mocap.trackers.shape_search import shifted
from mocap.trackers.silhouette_tracker import diffusion_std, internal_scale
from mocap.trackers.start_frames import (
    HypothesisTracks,
    chosen_hypothesis,
    start_hypotheses,
    track_hypotheses,
)
from mocap.trackers.tracker_settings import HybridSettings
from mocap.trackers.two_cue_shape import TwoCueState, fit_two_cue_shape


def restart_fraction(value: float) -> float:
    """A share of the first layer to restart, checked to lie in [0, 1]."""
    if not 0.0 <= float(value) <= 1.0:
        raise ValueError(f"restart fraction must be in [0, 1], got {value}")
    return float(value)


class RestartFirstLayer:
    """The APF's diffusion (:func:`~mocap.trackers.apf.perturb`), except on its first call
    (the first layer) a share ``fraction`` of the particles draw their free joint angles
    anew: the limb being searched is known to be wrong, and a Gaussian of a few degrees around
    it cannot reach a forearm folded the wrong way. Of those, a share ``from_library`` take the
    angles of a pose of a motion library (``library`` (T, D): rows of joint angles, NaN where
    the library has none; each row also mirrored left/right by the caller if wanted) with
    ``library_std`` (rad) of noise; the rest draw them uniformly within the joint limits. A
    uniform draw lands within 20 degrees of the right angle of each of an arm's four DOFs once
    in ~400 particles; the poses people take are a far smaller set."""

    def __init__(self, fraction: float, free: np.ndarray, library: np.ndarray | None = None,
                 from_library: float = 0.0, library_std: float = 0.1):
        self.fraction, self.free, self.first = restart_fraction(fraction), np.asarray(free, bool), True
        self.from_library = restart_fraction(from_library)
        self.library, self.library_std = library, float(library_std)

    def __call__(self, x, std, limits, rng, root_point=None):
        out = perturb(x, std, limits, rng, root_point)
        if self.first:
            self.first = False
            k = int(round(self.fraction * len(out)))
            cols = self.free & (np.arange(len(self.free)) >= 6) & np.all(np.isfinite(limits), axis=1)
            if k and cols.any():
                out[:k, cols] = rng.uniform(limits[cols, 0], limits[cols, 1], (k, int(cols.sum())))
                n = int(round(self.from_library * k)) if self.library is not None else 0
                if n:
                    rows = self.library[rng.integers(len(self.library), size=n)][:, cols]
                    drawn = rows + rng.normal(0.0, self.library_std, rows.shape)
                    known = np.isfinite(drawn)
                    block = out[:n, cols]
                    block[known] = drawn[known]
                    out[:n, cols] = np.clip(block, limits[cols, 0], limits[cols, 1])
        return out


#: the share of a stuck limb chain's search's first layer that draws the chain's angles anew (all of
#: those from the motion library when there is one): a quarter stays near the tracked pose
STUCK_RESTART = 0.75


def turned(shaped, chi: np.ndarray) -> np.ndarray:
    """The pose (D,) turned 180 degrees about the vertical (z) through its pelvis."""
    T = se3_exp(np.asarray(chi[:6], np.float64))
    pelvis = T[:3, :3] @ np.asarray(shaped.rest_joints[0], np.float64) + T[:3, 3]
    turn = np.diag([-1.0, -1.0, 1.0, 1.0])
    turn[:2, 3] = 2.0 * pelvis[:2]
    out = np.array(chi, np.float64)
    out[:6] = se3_log(turn @ T)
    return out


def library_poses(body: BodyModel, angles: np.ndarray, dof_names, mirrored: bool = True) -> np.ndarray:
    """Joint angles (T, n) named ``dof_names`` (a motion library: the pose prior's training
    poses) as rows (T, D) of the body's pose vector, NaN where the library has no value; with
    ``mirrored``, each pose also with its limbs swapped left/right (2T rows)."""
    rows = np.full((len(angles), body.num_dofs), np.nan)
    for i, n in enumerate(dof_names):
        if n in body.dof_names:
            rows[:, body.dof_index(n)] = angles[:, i]
    if not mirrored:
        return rows
    perm, sign = mirror_map(body)
    swapped = rows.copy()
    swapped[:, 6:] = sign * rows[:, 6:][:, perm]
    return np.vstack([rows, swapped])


def patrolled_chains(body: BodyModel, chains: list[tuple[int, list[int]]], which: str
                     ) -> list[tuple[int, list[int]]]:
    """The limb chains (root joint, its limbs) of ``chains`` that the patrol searches in turn
    (``apf.patrol_chains``): ``all`` of them, ``arms`` (root joint named ``l_shoulder`` /
    ``r_shoulder``) or ``legs`` (``l_hip`` / ``r_hip``), in their order. A ValueError naming the
    field when a selection finds no chain of the body."""
    if which == "all":
        return list(chains)
    root = {"arms": "shoulder", "legs": "hip"}[which]
    names = body.joint_names
    out = [c for c in chains if names[c[0]] in ("l_" + root, "r_" + root)]
    if not out:
        raise ValueError(f"apf.patrol_chains: {which!r} names no limb chain of body {body.name!r} "
                         f"(chains rooted at {[names[r] for r, _ in chains]})")
    return out


class HybridTracker(LocalTracker):
    """settings: :class:`HybridSettings`; prior: the pose prior when ``settings.apf.energy.prior``;
    library: the restarts' motion library (rows (T, D), :func:`library_poses`), None: the
    restarts draw uniformly within the joint limits."""

    def __init__(self, body: BodyModel, rig: Rig, rng: np.random.Generator, settings: HybridSettings,
                 prior: PosePrior | None = None, library: np.ndarray | None = None, name: str = "hybrid"):
        self.start_body = body             # the silhouette start's (its cache key does not hold limits)
        body = tracker_body(body, settings.joint_limits)
        super().__init__(body, rig, settings.local, name=name, rng=rng)
        self.tracker_settings, self.init_settings = settings, settings.initialization
        self.hybrid_settings = a = settings.apf
        self.rng, self.settings, self.weights, self.prior = rng, a.search, a.energy, prior
        self.scale, self.std0 = internal_scale(rig, a.resolution), diffusion_std(body, *a.init_std)
        self.refine_iterations, self.keep_particles = a.refine_iterations, settings.keep_particles
        self.restart = restart_fraction(a.restart)
        self.library, self.restart_from_library = library, restart_fraction(a.restart_from_library)
        self.patrol = int(a.patrol)
        self.patrol_agreement, self.patrol_margin = float(a.patrol_agreement), float(a.patrol_margin)
        self.heading_chains, self.heading_degrees = int(a.heading_chains), tuple(map(float, a.heading_angles))
        self.heading_turns: dict[int, float] = {}    # frame -> the turn (deg) the heading search kept
        self.stuck_frames, self.stuck_particles = int(a.stuck_frames), int(a.stuck_particles)
        self.stuck_searches: list[int] = []             # frames whose repair was the stuck chains' search
        self.chains = limb_chains(body)
        self.patrolled = patrolled_chains(body, self.chains, a.patrol_chains)
        self.streak = np.zeros(len(self.chains), int)   # frames in a row each limb chain was flagged
        self.energy_mesh = energy_mesh_for(body, a.energy_mesh)   # None: the full mesh
        self.cue = KeypointCue(body, rig, settings.keypoints) if settings.keypoints.enabled else None
        self.shape_prior: np.ndarray | None = None      # the silhouettes' shape, the keypoint fits' prior
        self.shape_moved = False         # a silhouette shape refinement was kept since the last keypoint fit
        two_cue = settings.keypoints.two_cue
        self.two_cue = TwoCueState(two_cue) if self.cue is not None and two_cue.enabled else None
        self.joint_offsets: np.ndarray | None = None   # the two-cue fit's skeleton (J, 3), None: none
        self.start_frames = settings.start_frames
        self.pending: list[Frame] | None = None     # the frames since the start, until it is chosen
        self.revised: dict[int, Estimate] = {}       # frame -> estimate tracked again from the chosen start
        self.start_choice: dict | None = None        # the start over frames' report
        self.start_cache = None                      # the start's cache folder (the restarts')
        self.self_initialised = False                # initializer() asked for (start_frames applies)

    def initialize(self, chi: np.ndarray, alpha: np.ndarray) -> None:
        super().initialize(chi, alpha)
        self.streak = np.zeros(len(self.chains), int)   # a new track: no chain flagged yet

    @property
    def budget(self) -> SearchBudget:
        return SearchBudget(self.settings.particles, self.settings.layers, tuple(self.weights.terms))

    def initializer(self, cache=None):
        """The silhouette initialisation (cached in ``cache``), then :meth:`refine_initial`."""
        from mocap.trackers.init_cache import Refined

        self.start_cache = cache            # the restarts' (``start_frames.restarts``)
        self.self_initialised = True        # the run starts from this start: start_frames applies
        return Refined(super().initializer(cache), self.refine_initial)

    def check_sequence(self, seq) -> None:
        """A ValueError before any work when ``seq`` has no masks, or (the keypoint cue on) no
        detections."""
        super().check_sequence(seq)
        if self.cue is not None:
            check_detections(seq, self.name)

    def refine_initial(self, frame: Frame, chi: np.ndarray, alpha: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, dict]:
        """The self-initialisation's pose (D,) and shape (K,) refined with the keypoint cue on
        ``frame``. With ``keypoints.shape_std`` > 0 the shape is first fitted to the keypoints'
        bone lengths (:meth:`KeypointCue.fitted_shape`). Silhouettes hardly tell front from back
        or left from right; keypoints do: the pose, its
        limbs swapped left/right and both turned 180 degrees about the vertical through the
        pelvis are each fitted by the local optimiser with the keypoints, and the one of lowest
        silhouette + marker energy goes on; then every limb chain in turn is searched (as a
        misaligned limb is, its pose kept where that energy falls), and the local optimiser
        ends (kept where it falls too). Returns (pose, shape, report); without the cue and with
        ``start_search``: :meth:`search_start`; otherwise without the cue (or with
        ``keypoints.init`` off, or no detections in the frame): pose and shape unchanged and {}."""
        on = self.cue is not None and self.tracker_settings.keypoints.init
        obs = self.cue.observe(frame) if on else None
        if obs is None:
            if self.cue is None and self.tracker_settings.start_search:
                return self.search_start(frame, chi, alpha)
            return chi, alpha, {}
        self.initialize(chi, alpha)
        report = {}
        if self.tracker_settings.keypoints.shape_std > 0:
            self.shape_prior = np.asarray(alpha, np.float64)
            if self.tracker_settings.keypoints.shape_frames > 1:
                self.cue.add_shape_sample(obs)
            alpha, report["keypoint_shape"] = self.cue.fitted_shape(obs, alpha)
            self.set_shape(alpha)
        before = float(self.two_cue_energy(frame, obs, chi[None])[0])
        perm, sign = mirror_map(self.body)
        starts = [chi, swap_limbs(chi, perm, sign, self.body.limits)]
        starts += [turned(self.shaped, c) for c in starts]
        fitted = np.stack([self.local_step(frame, c, extra=self.keypoint_lines(obs))[0] for c in starts])
        e = self.two_cue_energy(frame, obs, np.vstack([chi[None], fitted]))
        chi = np.vstack([chi[None], fitted])[int(np.argmin(e))]
        chi, after, _ = self.search_chains(frame, chi, lambda poses: self.two_cue_energy(frame, obs, poses),
                                           obs, extra=self.keypoint_lines(obs))
        report["keypoint_refine"] = {"energy_before": before, "energy_after": after}
        if self.two_cue is not None:
            self.two_cue.add(frame.index, chi, frame.masks, self.cue.triangulated(obs), True, (frame, obs))
        return chi, np.asarray(self.shaped.alpha, np.float64), report

    def search_start(self, frame: Frame, chi: np.ndarray, alpha: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, dict]:
        """The silhouette-only start refined (``start_search``): every limb chain of the pose
        ``chi`` (D,) searched in turn as a misaligned limb is (:meth:`search`), its pose kept where
        the frame's mean per-view E_S falls, then the local optimiser (kept where E_S falls too).
        Returns (pose, shape ``alpha`` unchanged, report: E_S before and after, chains kept)."""
        self.initialize(chi, alpha)
        target = silhouette_target(frame.masks, self.scale, view_names=tuple(self.rig.names))

        def e_s(poses: np.ndarray) -> np.ndarray:
            return self.sil.per_view(poses, target)[:, target.valid].mean(axis=1)

        before = float(e_s(chi[None])[0])
        chi, after, kept = self.search_chains(frame, chi, e_s)
        return chi, np.asarray(alpha), {"start_search": {"energy_before": before, "energy_after": after,
                                                         "chains_kept": kept}}

    def search_chains(self, frame: Frame, chi: np.ndarray, energy, obs=None, extra=None
                      ) -> tuple[np.ndarray, float, list[str]]:
        """Every limb chain of the pose ``chi`` (D,) searched in turn as a misaligned limb is
        (:meth:`search`, with the keypoint observation ``obs`` where given), its pose kept where
        ``energy`` ((P, D) -> (P,)) falls, then the local optimiser (with the ``extra``
        correspondences), kept where it falls too: the starts' refinement of both cues.
        Returns (pose, its energy, the root joints of the chains kept)."""
        kept = []
        for root, limbs in self.chains:
            flagged = np.zeros(self.body.num_joints, bool)
            flagged[limbs] = True
            free = self.detector.free_dofs(LimbCheck(flagged, [], {}))
            found, _, _ = self.search(frame, chi, chi, free, obs)
            e = energy(np.stack([chi, found]))
            if e[1] < e[0]:
                chi = found
                kept.append(self.body.joint_names[root])
        local, _ = self.local_step(frame, chi, extra=extra)
        e = energy(np.stack([chi, local]))
        if e[1] < e[0]:
            return local, float(e[1]), kept
        return chi, float(e[0]), kept

    def two_cue_energy(self, frame: Frame, obs, chi: np.ndarray) -> np.ndarray:
        """(P, D) -> (P,): the frame's mean per-view E_S plus the scaled marker likelihood."""
        target = silhouette_target(frame.masks, self.scale, view_names=tuple(self.rig.names))
        e = self.sil.per_view(chi, target)[:, target.valid].mean(axis=1)
        return e + self.cue.scaled(self.cue.energy(self.shaped, obs), chi)

    def keypoint_lines(self, obs):
        """The local optimiser's ``extra`` correspondences of this frame (None: no cue)."""
        if obs is None:
            return None
        return lambda chi: self.cue.lines(self.shaped, chi, obs)

    def search(self, frame: Frame, chi: np.ndarray, predicted: np.ndarray, free: np.ndarray, obs=None,
               stuck: bool = False):
        """The APF over the ``free`` DOFs from ``chi``: (pose, anneal trace, energy). ``stuck``: a
        limb chain flagged ``apf.stuck_frames`` frames in a row; the search has
        ``apf.stuck_particles`` particles, and three quarters of its first layer take the searched
        angles from the motion library (:class:`RestartFirstLayer`)."""
        target = silhouette_target(frame.masks, self.scale, view_names=tuple(self.rig.names))
        settings, restart, from_library = self.settings, self.restart, self.restart_from_library
        if stuck:
            settings = dataclasses.replace(settings, particles=self.stuck_particles)
            restart, from_library = STUCK_RESTART, (1.0 if self.library is not None else 0.0)
        markers = None
        if obs is not None:
            marker_energy = self.cue.energy(self.shaped, obs)
            markers = lambda x: self.cue.scaled(marker_energy, x)       # noqa: E731
        energy = FrameEnergy(self.weights, self.sil, target, predicted, self.prior, markers=markers)
        chi_apf, apf = anneal(energy, chi, self.std0, self.body.limits, settings, self.rng,
                              propagate=RestartFirstLayer(restart, free, self.library, from_library),
                              free=free,
                              keep_particles=self.keep_particles,
                              root_point=self.shaped.rest_joints[0])
        return chi_apf, apf, energy

    def search_heading(self, frame: Frame, chi: np.ndarray, obs=None) -> np.ndarray:
        """The pose ``chi`` (D,) turned about the vertical through its pelvis by each of
        ``apf.heading_angles`` and refined by the local step from each; of those and ``chi``, the
        one with the lowest mean per-view E_S (plus the marker likelihood with the keypoint cue),
        recorded in ``heading_turns`` when turned: the limb search's start where most chains are
        flagged (:mod:`mocap.trackers.heading`)."""
        turned_poses = turned_by(self.shaped.rest_joints[0], chi, np.deg2rad(self.heading_degrees))
        fitted = [self.local_step(frame, c, extra=self.keypoint_lines(obs))[0] for c in turned_poses]
        poses = np.stack([chi, *fitted])
        target = silhouette_target(frame.masks, self.scale, view_names=tuple(self.rig.names))
        e = self.sil.per_view(poses, target)[:, target.valid].mean(axis=1)
        if obs is not None:
            e = e + self.cue.scaled(self.cue.energy(self.shaped, obs), poses)
        best = int(np.argmin(e))
        if best:
            self.heading_turns[frame.index] = self.heading_degrees[best - 1]
        return poses[best]

    def patrol_check(self, frame: Frame, check: LimbCheck) -> LimbCheck | None:
        """On every ``patrol``-th frame whose check flagged nothing, the check with one limb chain
        flagged in turn (arms and legs round-robin), to be searched as if misaligned: a forearm
        bent the wrong way inside the silhouettes can pass both sides of the check for many
        frames while the silhouette energy still prefers the right pose (README, mismatch box).
        None: no patrol this frame."""
        if not self.patrol or check.names or not self.patrolled or frame.index % self.patrol:
            return None
        _, limbs = self.patrolled[(frame.index // self.patrol) % len(self.patrolled)]
        flagged = np.zeros(self.body.num_joints, bool)
        flagged[limbs] = True
        return dataclasses.replace(check, flagged=flagged, names=[self.body.joint_names[j] for j in limbs])

    def refit_shape(self) -> dict | None:
        """Once the keypoints of ``keypoints.shape_frames`` (> 1) frames are triangulated, fit the
        shape to their median bone lengths (:meth:`KeypointCue.shape_over_frames`, the prior on the
        silhouettes' shape) and track on with it; its report (None: not this frame). With
        ``keypoints.shape_follow`` the prior is centred on the current shape, and the fit is made
        again (to all frames so far) after every kept silhouette shape refinement."""
        cue = self.cue
        if cue is None or cue.settings.shape_frames < 2 or self.two_cue is not None:
            return None
        n, follow = len(cue.shape_samples), cue.settings.shape_follow
        first = self.shape_prior is not None and n == cue.settings.shape_frames
        again = follow and self.shape_prior is None and self.shape_moved and n > cue.settings.shape_frames
        if not (first or again):
            return None
        alpha, report = cue.shape_over_frames(np.asarray(self.shaped.alpha, np.float64) if follow
                                              else self.shape_prior)
        self.shape_prior, self.shape_moved = None, False
        self.set_shape(alpha)
        return report

    def fit_two_cue(self) -> dict | None:
        """With ``keypoints.two_cue`` on, once its ``frames`` frames are tracked (and every
        ``every`` frames after), the shape fitted to both cues over the frames so far
        (:func:`~mocap.trackers.two_cue_shape.fit_two_cue_shape`, poses held), the history moved
        by the shift that came with it; its report (None: not this frame)."""
        state = self.two_cue
        if state is None or self.cue.landmarks is None or not state.due():
            return None
        chosen = state.chosen()
        chis = np.stack([c for _, c, _ in chosen]) if chosen else np.zeros((0, self.body.num_dofs))
        found = fit_two_cue_shape(self.body, self.rig, self.cue.landmarks, np.asarray(self.shaped.alpha),
                                  np.stack(state.measured), chis, [m for _, _, m in chosen],
                                  state.settings, self.init_rng)
        state.fits += 1
        state.reports.append({"frame": len(state.measured), **found.report})
        self.set_shape(found.alpha)

        def move(c):
            return shifted(c, found.shift)

        self.history = [move(c) for c in self.history]
        state.shifted(move)
        if state.settings.skeleton > 0:
            frames, chis, measured = state.skeleton_frames()
            for i, f in enumerate(frames if state.settings.skeleton_refit else ()):
                frame, obs = state.observed[f]              # the poses re-fitted on the new shape
                for _ in range(state.settings.skeleton_refit):
                    chis[i] = self.local_step(frame, chis[i], extra=self.keypoint_lines(obs))[0]
            if len(chis):
                fit = fit_joint_offsets(self.body, self.cue.landmarks, found.alpha, chis, measured,
                                        std=state.settings.skeleton, noise=state.settings.skeleton_noise,
                                        rest_offsets=self.cue.offsets, start=self.joint_offsets)
                self.joint_offsets = fit.offsets
                state.reports[-1]["skeleton"] = fit.report
                self.set_shape(found.alpha)
        return found.report

    def refine_shape(self, frame: Frame, chi: np.ndarray, aligned: bool = True):
        """The silhouette-only refinement (:meth:`LocalTracker.refine_shape`), off where the
        two-cue fit (``keypoints.two_cue``) takes its place."""
        if self.two_cue is not None:
            return chi, None
        return super().refine_shape(frame, chi, aligned)

    def set_shape(self, alpha: np.ndarray, joint_offsets: np.ndarray | None = None) -> None:
        """Track on with the shape ``alpha`` (K,) and the rest-joint corrections ``joint_offsets``
        (J, 3); None: those the two-cue fit found (``keypoints.two_cue.skeleton``), if any."""
        super().set_shape(alpha, self.joint_offsets if joint_offsets is None else joint_offsets)
        self.sil = SilhouetteEnergy(self.shaped, self.rig, self.scale, mesh=self.energy_mesh)

    @property
    def revises_tracks(self) -> bool:
        """With ``start_frames`` on, in a run it applies to (self-initialised, no keypoint cue: see
        :meth:`begin`), the first frames' answers may be replaced once the start is chosen over them
        (:meth:`final_tracks`); a run from a given pose is recorded as it goes."""
        chosen_later = self.start_frames.frames > 0 and self.self_initialised and self.cue is None
        return super().revises_tracks or chosen_later

    def begin(self, frame: Frame, initial):
        """As :class:`OnePerson`'s; with ``start_frames`` on, no keypoint cue and a run that starts
        from the tracker's own self-initialisation (:meth:`initializer` asked for; not a given
        pose such as ground truth plus noise), the start is kept with its frame to be chosen
        among its alternatives over the next frames."""
        out = super().begin(frame, initial)
        self.revised, self.start_choice = {}, None
        if self.start_frames.frames > 0 and self.cue is None and self.self_initialised:
            self.pending = [frame]
            self.start_pose = np.array(initial[0].chi, np.float64)
            self.start_alpha = np.array(initial[0].alpha, np.float64)
        return out

    def final_tracks(self, tracks):
        """The tracks with the frames tracked again from a start chosen over frames
        (``start_frames``) in place of those first answered, then as :class:`LocalTracker`'s."""
        if self.revised and 0 in tracks:
            tracks = {**tracks, 0: {**tracks[0], **self.revised}}
        return super().final_tracks(tracks)

    def step(self, frame: Frame) -> Estimate:
        """The frame's estimate (:meth:`track_step`); with ``start_frames`` = N on, once frames
        0..N are seen, the start chosen over them (:meth:`choose_start`)."""
        est = self.track_step(frame)
        if self.pending is not None:
            self.pending.append(frame)
            if len(self.pending) > self.start_frames.frames:
                est = self.choose_start(est)
        return est

    def restarts(self, frame: Frame) -> list[tuple[np.ndarray, np.ndarray]]:
        """``start_frames.restarts`` more silhouette self-initialisations of ``frame`` (the start's
        settings and body), each from its own generator seeded by a number drawn from a copy of the
        start's generator (the tracker's own draws unchanged), cached as the start is (in the
        folder given to :meth:`initializer`). Returns [(pose (D,), shape (K,))]."""
        from mocap.trackers.init_cache import Cached

        n = self.start_frames.restarts
        if not n:
            return []
        base = int(copy.deepcopy(self.init_rng).integers(2**62))
        out = []
        for k in range(1, n + 1):
            start = self.silhouette_start(np.random.default_rng([base, k]),
                                          progress=lambda stage, fraction: None)
            est, _ = Cached(start, self.start_cache)(frame)
            out.append((np.asarray(est[0].chi, np.float64), np.asarray(est[0].alpha, np.float64)))
        return out

    def start_tracks(self, frames: list[Frame]):
        """The start and its alternatives (:func:`~mocap.trackers.start_frames.start_hypotheses`;
        then the :meth:`restarts`, each with its own shape) each tracked by the local step alone
        over ``frames`` (the start's frame first; :func:`~mocap.trackers.start_frames.track_hypotheses`:
        contours only, each with its start's shape), scored by the mean per-view E_S; the tracker's
        state left as it was. Returns (names (H,), :class:`~mocap.trackers.start_frames.HypothesisTracks`,
        shapes (H, K))."""
        kept = (self.shaped, self.sil, self.history)
        plain = [dataclasses.replace(f, images=None) for f in frames]     # no SIFT: the main track's

        def step(frame, predicted):
            self.history = [predicted]
            return self.local_step(frame, predicted)[0]

        def energy(frame, poses):
            target = silhouette_target(frame.masks, self.scale, view_names=tuple(self.rig.names))
            return self.sil.per_view(poses, target)[:, target.valid].mean(axis=1)

        try:
            self.set_shape(self.start_alpha)
            starts, names = start_hypotheses(self.body, self.shaped.rest_joints[0], self.start_pose,
                                             self.start_frames.turns)
            groups = [(self.start_alpha, starts)]
            for k, (chi, alpha) in enumerate(self.restarts(frames[0]), 1):
                groups.append((alpha, chi[None]))
                names.append(f"restart_{k}")
            found, shapes = [], []
            for alpha, poses in groups:
                self.set_shape(alpha)
                found.append(track_hypotheses(poses, plain, step, energy, self.prediction_damping))
                shapes += [alpha] * len(poses)
            merged = HypothesisTracks(*(np.concatenate([getattr(f, k) for f in found])
                                        for k in ("starts", "poses", "energy")))
            return names, merged, np.stack(shapes)
        finally:
            self.shaped, self.sil, self.history = kept

    def choose_start(self, est: Estimate) -> Estimate:
        """The start chosen over the frames kept since it (:meth:`start_tracks`): where another
        hypothesis than the start has the lowest summed E_S by more than ``start_frames.margin``,
        the tracker starts again from that hypothesis (its pose as it was before the local step, as
        the start itself) and tracks those frames once
        more (their new estimates in ``revised``, the last one returned); otherwise ``est``, the
        tracking left as it was. ``start_choice``: the report."""
        frames, self.pending = self.pending, None
        names, found, shapes = self.start_tracks(frames)
        best = chosen_hypothesis(found.total, self.start_frames.margin)
        self.start_choice = {"frames": len(frames), "hypotheses": names,
                             "energy": [float(e) for e in found.total], "chosen": names[best]}
        if not best:
            return self.reporting_choice(est)
        chi0, alpha0 = found.starts[best], shapes[best]
        last = frames[-1].index
        self.stuck_searches = [f for f in self.stuck_searches if f > last]
        self.heading_turns = {f: a for f, a in self.heading_turns.items() if f > last}
        self.initialize(chi0, alpha0)
        self.revised = {frames[0].index: initial_estimate_of(chi0, alpha0)}
        for frame in frames[1:]:
            est = self.track_step(frame)
            self.revised[frame.index] = est
        est = self.revised[frames[-1].index] = self.reporting_choice(est)
        return est

    def reporting_choice(self, est: Estimate) -> Estimate:
        """``est`` with the start's choice in its diagnostics (the run's metrics read it there)."""
        return dataclasses.replace(est, diagnostics=dataclasses.replace(est.diagnostics,
                                                                        start_choice=self.start_choice))

    def track_step(self, frame: Frame) -> Estimate:
        """The hybrid's step on ``frame``: the local step, the check, the repair where flagged,
        the shape refinement."""
        if self.shaped is None:
            raise RuntimeError("initialize() the tracker before step()")
        t0 = time.perf_counter()
        obs = self.cue.observe(frame) if self.cue is not None else None
        self.refit_shape()
        self.fit_two_cue()
        predicted = predict_constant_velocity(self.history[-2:], self.prediction_damping)
        chi, local = self.local_step(frame, predicted, extra=self.keypoint_lines(obs))
        t1 = time.perf_counter()
        verts = self.shaped.pose(chi).vertices[0]
        check = self.detector(verts, frame.masks)
        if obs is not None:
            flagged = check.flagged | self.cue.misaligned(self.shaped, chi, obs)
            if (flagged != check.flagged).any():
                check = dataclasses.replace(check, flagged=flagged,
                                            names=[self.body.joint_names[j] for j in np.flatnonzero(flagged)])
        t2 = time.perf_counter()
        self.streak = (self.streak + 1) * chains_flagged(self.chains, check.flagged)
        patrol = self.patrol_check(frame, check)
        decision = Misalignment.of(check, apf_called=bool(check.names) or patrol is not None,
                                   patrol=patrol is not None)
        report = StepDiagnostics(local=local, misalignment=decision)
        timings = {"local": t1 - t0, "misalignment": t2 - t1}
        if decision.apf_called:
            free = self.detector.free_dofs(patrol or check)
            chi_local = chi
            if self.heading_chains and flagged_chains(self.chains, check.flagged) >= self.heading_chains:
                chi = self.search_heading(frame, chi, obs)
            stuck = bool(self.stuck_frames and patrol is None and (self.streak >= self.stuck_frames).any())
            if stuck:
                self.stuck_searches.append(frame.index)
            chi_apf, apf, energy = self.search(frame, chi, predicted, free, obs, stuck=stuck)
            target = energy.target
            t3 = time.perf_counter()
            chi, refine = self.local_step(frame, chi_apf, extra=self.keypoint_lines(obs),
                                          iterations=self.refine_iterations)
            per_view = self.sil.per_view(np.stack([chi_local, chi]), target)[:, target.valid]
            e_local, e_apf = per_view.mean(axis=1)
            if obs is not None:         # the two cues decide together
                e_local, e_apf = np.array([e_local, e_apf]) + energy.markers(np.stack([chi_local, chi]))
            accepted = bool(e_apf < e_local)
            if patrol is not None:
                # a patrolled limb was not flagged: keep the search's pose only where it
                # explains the silhouettes better by a margin and in enough of the views
                agree = float(np.mean(per_view[1] < per_view[0]))
                accepted = bool(accepted and e_apf < (1.0 - self.patrol_margin) * e_local
                                and agree >= self.patrol_agreement)
            if not accepted:
                chi = chi_local
            terms = {k: float(v[0]) for k, v in energy.terms(chi[None]).items()}
            decision = dataclasses.replace(
                decision, free_dofs=tuple(self.body.dof_names[d] for d in np.flatnonzero(free)),
                apf_accepted=accepted)
            report = dataclasses.replace(report, misalignment=decision, energy_terms=terms, anneal=apf,
                                         refine=refine, ignored_views=tuple(target.ignored))
            timings.update({"apf": t3 - t2, "refine": time.perf_counter() - t3})
            if accepted:
                verts = self.shaped.pose(chi).vertices[0]
        chi, shape = self.finish_step(frame, chi, verts, not check.names, timings)
        self.shape_moved = self.shape_moved or bool(shape is not None and shape.accepted)
        if obs is not None:
            self.cue.learn_offsets(self.shaped, chi, obs)
            if self.two_cue is not None:
                self.two_cue.add(frame.index, chi, frame.masks, self.cue.triangulated(obs), not check.names,
                                 (frame, obs))
            ks = self.cue.settings
            if ((self.shape_prior is not None and len(self.cue.shape_samples) < ks.shape_frames)
                    or (ks.shape_follow and ks.shape_std > 0 and ks.shape_frames > 1)):
                self.cue.add_shape_sample(obs)
        return Estimate(chi=chi, alpha=self.shaped.alpha,
                        diagnostics=dataclasses.replace(report, shape=shape, timings=timings),
                        joint_offsets=self.shaped.joint_offsets)
