"""Several people with the marker tracker (``marker_people``): one :class:`MarkerAPFTracker`
per person, identities kept across frames, people entering and leaving picked up.

Start-up (:meth:`PeopleTracker.start`): the people of the first frame are associated across
views by whole-skeleton epipolar consistency (:mod:`mocap.trackers.markers.associate`); each
person with support gets a track (id 0, 1, ... in the association's order: most views
first), initialised by the tracker's own start-up on that person's detections. Support
(:meth:`PeopleTracker.views_needed`): seen in ``options.min_views`` views (2: what
triangulation needs) and in more than ``options.support`` (half) of the views that should see
it, the views whose image holds its triangulated keypoints
(:func:`~mocap.trackers.markers.associate.views_expected`). A person standing outside the
other cameras' images is tracked from two views; a false skeleton that two cameras see where
three others see nobody is not. A person within ``options.radius`` of one started before it
is that one's leftover skeletons. Once tracked, a view where another tracked person nearer the
camera covers ``options.hidden`` of it does not count against it (occlusion).
``select`` keeps one of them: ``"all"``, ``"most_views"``, an ``int`` id,
or a point (x, y, z) world metres (the person whose triangulated keypoints lie nearest).

Each frame (:meth:`PeopleTracker.step`):

1. Assignment: every live track predicts its landmarks; in each view the detector's
   skeletons are assigned to tracks by the Hungarian method on the median pixel distance
   between a skeleton's keypoints and the track's predicted projections, gated at the
   likelihood's gate. Each track runs its annealed search on its own skeletons only, so a
   crossing person's keypoints cannot pull a track across (identities are kept through
   crossings); a track with no skeleton coasts on its prediction (short occlusions). A track
   coming back after missed frames, or assigned skeletons in fewer views than the frame
   before, takes them only when they triangulate within ``options.radius`` m of its
   prediction (a newcomer where someone just left is not taken for them), and after coasting
   more than ``options.confirm_frames`` frames only in the views its support needs (from its
   predicted keypoints). In a track's own views, a skeleton that disagrees with the others
   (its median skeleton epipolar distance to them above ``options.consistency`` times the
   frame's reference, the median over every track's pairs of views) is not taken (a false
   skeleton, or the crossing partner's).
2. Deaths: a track with no skeleton for more than ``options.max_missed`` frames ends; the
   frames it coasted after its last skeleton are dropped from its estimates. A track assigned
   skeletons in fewer views than its support needs (but some) for more than
   ``options.max_under_viewed`` consecutive frames ends too (a ghost living on a detector's
   false skeletons seen by one or two cameras: its support went), its frames after the last
   one with support dropped.
3. Births: the skeletons no track took are associated across views as at the start-up
   (with support: a false skeleton seen by one or two cameras that others should see is no
   newcomer; and ``options.consistency``: the views must agree about as well as a tracked
   person's do, not by the chance agreement of false skeletons); each such person, triangulated, is a
   candidate unless it lies within ``options.radius`` m of a live track (its median keypoint
   against the track's median landmark; tracks coasting for more than ``confirm_frames``
   aside). A candidate seen in ``options.confirm_frames`` consecutive frames, each within
   ``radius`` of the frame before, is confirmed: a new track (the next id) initialised by the
   marker tracker's own start-up on that frame's detections of the person.

Ids are never reused. ``births`` and ``deaths`` record, per frame, the ids born and ended.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from mocap.data.sequence import Detections
from mocap.energy.epipolar import symmetric_epipolar_distance
from mocap.energy.markers import arrange_detections, pinhole_project
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.contract import FrameEstimate, Needs, SearchBudget, Tracks, Uncached
from mocap.trackers.diagnostics import StepDiagnostics
from mocap.trackers.markers.associate import (
    Skeletons,
    associate_people,
    person_detections,
    projected_boxes,
    skeletons_of,
    views_expected,
)
from mocap.trackers.markers.batch import PeopleEnergy, anneal_people
from mocap.trackers.markers.refine import refine_people
from mocap.trackers.markers.settings import PeopleOptions
from mocap.trackers.markers.startup import triangulate_candidates
from mocap.trackers.markers.tracker import MarkerAPFTracker


@dataclass
class Track:
    """One person: ``born`` the frame of its first estimate, ``last_seen`` the last frame with a
    skeleton assigned, ``views`` the views it was last assigned skeletons in, ``last_well`` the
    last frame it was assigned skeletons in the views its support needs, ``under`` the frames
    since then with skeletons in fewer views, ``ended`` once it has been missed for more than
    ``max_missed`` frames or under-viewed for more than ``max_under_viewed``; ``estimates``:
    {frame: estimate} (no entries after ``last_seen``, resp. ``last_well``, once ended)."""

    id: int
    tracker: MarkerAPFTracker
    born: int = 0
    last_seen: int = 0
    missed: int = 0
    views: int = 0
    last_well: int = 0
    under: int = 0
    ended: bool = False
    estimates: dict[int, Estimate] = field(default_factory=dict)


@dataclass
class Candidate:
    """A person no track explains: ``centre`` (3,) median triangulated keypoint world m,
    ``frames`` consecutive frames seen, ``detections`` of the latest frame."""

    centre: np.ndarray
    frames: int
    detections: Detections


def _only(det: Detections, keep: np.ndarray) -> Detections:
    return Detections(det.labels, det.frame[keep], det.view[keep], det.label[keep], det.xy[keep],
                      det.confidence[keep], None if det.person is None else det.person[keep])


def masked_median(d: np.ndarray, ok: np.ndarray, min_count: int = 1, missing: float = np.inf) -> np.ndarray:
    """Median of d (..., N) over its entries where ok (..., N) (the values of ``np.median`` on
    them), ``missing`` where fewer than ``min_count``: (...)."""
    n = ok.sum(axis=-1)
    srt = np.sort(np.where(ok, d, np.inf), axis=-1)
    hi = np.take_along_axis(srt, np.minimum(n // 2, srt.shape[-1] - 1)[..., None], -1)[..., 0]
    lo = np.take_along_axis(srt, np.maximum(n // 2, 1)[..., None] - 1, -1)[..., 0]
    with np.errstate(invalid="ignore"):
        med = np.where(n % 2 == 1, hi, (lo + hi) / 2)
    return np.where(n >= max(min_count, 1), med, missing)


def skeleton_costs(xy: np.ndarray, valid: np.ndarray, u: np.ndarray, front: np.ndarray,
                   min_points: int = 3, missing: float = 1e9) -> np.ndarray:
    """(T, S) median pixel distance between each of S skeletons xy (S, L, 2) (valid (S, L))
    and each of T tracks' projected landmarks u (T, L, 2) (front (T, L)), over the keypoints
    valid and in front of the camera; ``missing`` where fewer than ``min_points``. The values
    of ``np.median`` on each pair's distances, all pairs at once."""
    d = np.linalg.norm(xy[None] - u[:, None], axis=-1)                      # (T, S, L)
    return masked_median(d, valid[None] & front[:, None], min_points, missing)


class PeopleTracker:
    """make_tracker: () -> a fresh MarkerAPFTracker (same body, rig, settings; own rng);
    options: :class:`~mocap.trackers.markers.settings.PeopleOptions`. See the module docstring.

    As a :class:`~mocap.trackers.contract.Tracker`: its start (``initializer``) finds and starts
    every person of the first frame (:meth:`start`), ``track`` is :meth:`step`, and its final
    tracks are :meth:`estimates_by_person` (a departed person's coasted frames dropped)."""

    several_people = True
    revises_tracks = False       # final_tracks: the tracks as answered, ended ones included
    needs = Needs(detections=True)
    budget = SearchBudget()

    def __init__(self, make_tracker: Callable[[], MarkerAPFTracker], options: PeopleOptions | None = None,
                 select: str | int | Sequence[float] = "all", name: str = "marker_people"):
        self.make_tracker, self.select, self.name = make_tracker, select, name
        self.options = options if options is not None else PeopleOptions()
        self.tracks: list[Track] = []
        self.candidates: list[Candidate] = []
        self.births: dict[int, list[int]] = {}
        self.deaths: dict[int, list[int]] = {}
        self.start_up_flags: list[str] = []
        self._probe: MarkerAPFTracker | None = None
        self._reference: float | None = None        # px: how well a tracked person's views agree
        self._needed: list[int] = []                 # per live track: views its support needs

    # -- set-up ------------------------------------------------------------------------
    def check_sequence(self, seq) -> None:
        """Raise a one-line ValueError before any work when ``seq`` cannot be tracked: no
        detections, labels the landmark set does not know, or no skeleton grouping
        (``Detections.person``) to tell people apart."""
        self._probe_tracker().check_sequence(seq)
        det = seq.detections
        if det.person is None or np.all(det.person < 0):
            raise ValueError(f"{self.name}: sequence {seq.name!r} has no skeleton grouping "
                             "(Detections.person): several people need the detector's per-view person "
                             "index (for a keypoint recording: data.person=all)")

    def _probe_tracker(self) -> MarkerAPFTracker:
        if self._probe is None:
            self._probe = self.make_tracker()
        return self._probe

    def start(self, frame: Frame) -> list[Track]:
        probe = self._probe_tracker()
        probe._landmarks_for(frame)
        det = frame.detections
        sk = skeletons_of(det, probe.landmarks.names, probe.rig)
        if sk is None:
            raise ValueError("several people need detections grouped into skeletons (Detections.person)")
        people = associate_people(sk, probe.F, self._association_px(), min_views=self.min_views)
        people = self._supported(det, sk, people)
        if self.options.consistency and people:
            self._reference = float(np.median([d for _, d, _ in people]))
            people = [(p, d, c) for p, d, c in people if d <= self.options.consistency * self._reference]
        tracks = [self._new_track(n, frame.index, person_detections(det, sk, person))
                  for n, (person, _, _) in enumerate(people)]
        self.tracks = self._chosen(tracks)
        self.births = {frame.index: [t.id for t in self.tracks]}
        self.deaths = {}
        self.candidates = []
        return self.tracks

    @property
    def min_views(self) -> int:
        """Views a person must be associated in whatever the others show (``options.min_views``)."""
        return self.options.min_views

    def views_needed(self, points: np.ndarray, seen: np.ndarray, others: Sequence[np.ndarray]) -> int:
        """Views a person with keypoints ``points`` (L, 3) world m (NaN: unknown), seen in the
        views ``seen`` (C,) bool, must be seen in (:meth:`PeopleOptions.views_needed`): more than
        ``options.support`` of the views that should see it
        (:func:`~mocap.trackers.markers.associate.views_expected`: its keypoints in the image, no
        one of ``others`` (each (L', 3) world m: the other people known) nearer the camera
        covering ``options.hidden`` of its box), the views it is seen in counted among them."""
        u, depth = self._project(points[None])
        if others:
            ou, odepth = self._project(np.stack(others))
        else:
            C = len(seen)
            ou, odepth = np.zeros((0, 1, C, 2)), np.zeros((0, 1, C))
        return self._needed_at(u[0], depth[0], seen, *projected_boxes(ou, odepth))

    def _project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """points (P, L, 3) world m (NaN: unknown) -> undistorted pixels (P, L, C, 2) and depths
        (P, L, C), NaN where unknown."""
        u, depth = pinhole_project(self._probe_tracker().pinhole, np.where(np.isfinite(points), points, 0.0))
        bad = ~np.all(np.isfinite(points), axis=-1)
        u[bad], depth[bad] = np.nan, np.nan
        return u, depth

    def _needed_at(self, u: np.ndarray, depth: np.ndarray, seen: np.ndarray, others_box: np.ndarray,
                   others_depth: np.ndarray) -> int:
        """:meth:`views_needed` of keypoints projected to u (L, C, 2) at depth (L, C), the
        others' boxes (P, C, 4) and depths (P, C) (:func:`projected_boxes`)."""
        sizes = np.asarray(self._probe_tracker().pinhole.sizes)
        expected = views_expected(u, depth, sizes, others_box, others_depth, self.options.hidden) | seen
        return self.options.views_needed(int(expected.sum()))

    def _supported(self, det: Detections, free: Skeletons, people: list[tuple[list[int | None], float]]
                   ) -> list[tuple[list[int | None], float, np.ndarray]]:
        """The associated people (skeleton indices in ``free``) seen in the views their support
        needs (:meth:`views_needed`, no one counted as hiding them: a newcomer shows itself in
        most of the views whose image holds it), as (person, distance, triangulated keypoints
        (L, 3)); a person that triangulates (median keypoint) within ``options.radius`` of one
        kept before it is that one's leftover skeletons, dropped."""
        kept = []
        for person, d in people:
            X = self._points(person_detections(det, free, person))
            if np.isfinite(X[:, 0]).sum() < 3:
                continue
            seen = np.array([i is not None for i in person])
            if seen.sum() < self.views_needed(X, seen, []):
                continue
            centre = np.nanmedian(X, axis=0)
            if any(np.linalg.norm(centre - np.nanmedian(k[2], axis=0)) < self.options.radius for k in kept):
                continue
            kept.append((person, d, X))
        return kept

    def _association_px(self) -> float:
        probe = self._probe_tracker()
        return probe.init.association_px or probe.likelihood.gate_px

    def _new_track(self, track_id: int, f: int, det: Detections) -> Track:
        trk = self.make_tracker()
        chi, alpha = trk.initial_estimate(Frame(f, detections=det))
        trk.initialize(chi, alpha)
        self.start_up_flags += [f"person {track_id}: {flag}" for flag in trk.start_up_flags]
        t = Track(track_id, trk, born=f, last_seen=f, last_well=f)
        t.estimates[f] = Estimate(chi=chi, alpha=np.asarray(alpha, np.float64),
                                  diagnostics=StepDiagnostics(initial=True))
        return t

    def _chosen(self, tracks: list[Track]) -> list[Track]:
        s = self.select
        if isinstance(s, str):
            if s == "all":
                return tracks
            if s == "most_views":
                return tracks[:1]
            raise ValueError(f"select must be 'all', 'most_views', an id or a point, got {s!r}")
        if isinstance(s, int | np.integer):
            if not 0 <= s < len(tracks):
                raise ValueError(f"person id {s} not found ({len(tracks)} people in the first frame)")
            return [tracks[s]]
        point = np.asarray(s, np.float64)
        d = [np.linalg.norm(self._landmarks(t).mean(axis=0) - point) for t in tracks]
        return [tracks[int(np.argmin(d))]]

    @staticmethod
    def _landmarks(t: Track, chi: np.ndarray | None = None) -> np.ndarray:
        trk = t.tracker
        chi = trk.history[-1] if chi is None else chi
        return trk.landmark_positions(chi[None])[0].astype(np.float64)

    # -- per frame ---------------------------------------------------------------------
    def assign(self, frame: Frame, live: list[Track],
               sk: Skeletons | None = None) -> tuple[list[np.ndarray], list[list[tuple[int, int]]]]:
        """Per live track, the (N,) bool rows of the frame's detections assigned to it and the
        skeletons (view, index in ``sk``) they come from."""
        det = frame.detections
        probe = self._probe_tracker()
        self._needed = [self.min_views for _ in live]
        if sk is None:
            sk = skeletons_of(det, probe.landmarks.names, probe.rig)
        if sk is None:                                      # no grouping: everyone sees everything
            return [np.ones(len(det), bool) for _ in live], [[] for _ in live]
        keep = [np.zeros(len(det), bool) for _ in live]
        taken: list[list[tuple[int, int]]] = [[] for _ in live]
        if not live:
            return keep, taken
        pred = np.stack([self._landmarks(t, t.tracker.predict()) for t in live])     # (T, L, 3)
        u, depth = pinhole_project(probe.pinhole, pred)                             # (T, L, C, 2)
        gate = probe.likelihood.gate_px
        for c in range(len(sk.xy)):
            S = len(sk.xy[c])
            if not S:
                continue
            cost = skeleton_costs(sk.xy[c], sk.valid[c], u[:, :, c], depth[:, :, c] > 0)
            rows, cols = linear_sum_assignment(cost)
            for i, j in zip(rows, cols, strict=True):
                if cost[i, j] < gate:
                    taken[i].append((c, int(j)))
        if self.options.consistency:
            taken = self._consistent(sk, taken)
        self._needed = []
        boxes, near = projected_boxes(u, depth)                                     # (T, C, 4), (T, C)
        for i, tk in enumerate(taken):
            seen = np.isin(np.arange(len(sk.xy)), [c for c, _ in tk])
            rest = np.arange(len(live)) != i
            self._needed.append(self._needed_at(u[i], depth[i], seen, boxes[rest], near[rest]))
        for i, tk in enumerate(taken):
            for c, j in tk:
                keep[i] |= (det.view == c) & (det.person == sk.ids[c][j])
        return keep, taken

    def _consistent(self, sk: Skeletons, taken: list[list[tuple[int, int]]]) -> list[list[tuple[int, int]]]:
        """Each track's skeletons without the views that disagree with its others: a view whose
        median skeleton epipolar distance to the track's other views exceeds
        ``options.consistency`` times the reference (a false skeleton, or the crossing
        partner's, taken in that view) is dropped (tracks with 3 or more views). Updates the
        reference: the median of these distances over every track's pairs of views."""
        F = self._probe_tracker().F
        C = len(sk.xy)
        d = np.full((len(taken), C, C), np.nan)
        pooled = []
        views = [dict(tk) for tk in taken]
        for a, b in itertools.combinations(range(C), 2):
            have = [(i, v[a], v[b]) for i, v in enumerate(views) if a in v and b in v]
            if not have:
                continue
            ia, ja, jb = (np.array(v) for v in zip(*have, strict=True))
            # skeleton_epipolar_distance of each track's pair (its min_common = 4 landmarks)
            D = masked_median(symmetric_epipolar_distance(F[a, b], sk.xy[a][ja], sk.xy[b][jb]),
                              sk.valid[a][ja] & sk.valid[b][jb], 4)
            d[ia, a, b] = d[ia, b, a] = D
            pooled.append(D[np.isfinite(D)])
        pooled = np.concatenate(pooled) if pooled else np.zeros(0)
        if len(pooled):
            self._reference = float(np.median(pooled))
        if self._reference is None:
            return taken
        med = masked_median(d, np.isfinite(d), 1, 0.0)                          # (T, C)
        limit = self.options.consistency * self._reference
        return [[(c, j) for c, j in tk if not med[i, c] > limit] if len(tk) >= 3 else tk
                for i, tk in enumerate(taken)]

    def step(self, frame: Frame) -> dict[int, Estimate]:
        """{track id: estimate} for the tracks live in this frame (a track born here: its
        initial estimate)."""
        f = frame.index
        det = frame.detections
        probe = self._probe_tracker()
        probe._landmarks_for(frame)
        sk = skeletons_of(det, probe.landmarks.names, probe.rig) if det is not None and len(det) else None
        live = [t for t in self.tracks if not t.ended]
        if live and sk is not None:
            rows, taken = self.assign(frame, live, sk)
        else:
            rows, taken = [np.zeros(0 if det is None else len(det), bool) for _ in live], [[] for _ in live]
            self._needed = [self.min_views for _ in live]
        used: list[set[int]] = [set() for _ in (sk.xy if sk is not None else ())]
        out = {}
        stepping: list[tuple[Track, Frame]] = []
        for t, mine, tk, needed in zip(live, rows, taken, self._needed, strict=True):
            # back after missed frames, or seen in fewer views than before: someone else may be
            # standing where the track coasts (a newcomer next to where a person left); back
            # after coasting longer than confirm_frames only in the views its support needs,
            # as a newcomer
            if mine.any() and t.missed > self.options.confirm_frames and len(tk) < needed:
                mine = np.zeros_like(mine)
                tk = []
            if mine.any() and (t.missed or len(tk) < t.views) and not self._same_person(t, _only(det, mine)):
                mine = np.zeros_like(mine)
                tk = []
            if tk:
                t.views = len(tk)
                if len(tk) >= needed:
                    t.last_well, t.under = f, 0
                else:
                    t.under += 1
            for c, j in tk:
                used[c].add(j)
            if mine.any():
                t.missed, t.last_seen = 0, f
            else:
                t.missed += 1
                if t.missed > self.options.max_missed:
                    t.ended = True
                    for g in [g for g in t.estimates if g > t.last_seen]:
                        del t.estimates[g]
                    self.deaths.setdefault(f, []).append(t.id)
                    continue
            if t.under > self.options.max_under_viewed:      # a ghost on false skeletons, or gone
                t.ended = True
                for g in [g for g in t.estimates if g > t.last_well]:
                    del t.estimates[g]
                self.deaths.setdefault(f, []).append(t.id)
                continue
            stepping.append((t, Frame(f, detections=_only(det, mine))))
        for t, est in zip([t for t, _ in stepping], self._step_tracks(stepping), strict=True):
            t.estimates[f] = est
            out[t.id] = est
        if self.options.births and sk is not None:
            for t in self._births(frame, sk, used):
                out[t.id] = t.estimates[f]
        return out

    def _step_tracks(self, stepping: list[tuple[Track, Frame]]) -> list[Estimate]:
        """Each track's step on its frame (its own detections): the annealed searches of all of
        them run together (:func:`mocap.trackers.markers.batch.anneal_people`: one energy call
        per layer for every person's particles, then their refinements together, each person's
        result as its own step gives); one track alone, or trackers that cannot share a batch,
        step one by one."""
        trackers = [t.tracker for t, _ in stepping]
        if not self._batchable(trackers):
            return [trk.step(frame) for trk, (_, frame) in zip(trackers, stepping, strict=True)]
        t0 = time.perf_counter()
        predicted = [trk.predict() for trk in trackers]
        built = [trk.frame_energy(frame, p) for trk, (_, frame), p in zip(trackers, stepping, predicted,
                                                                          strict=True)]
        t1 = time.perf_counter()
        first = trackers[0]
        found = anneal_people(PeopleEnergy([e for e, _ in built]), np.stack(predicted), first.std0,
                              first.body.limits, first.settings, [trk.rng for trk in trackers],
                              np.stack([trk.history[-1] for trk in trackers]),
                              [trk.shaped.rest_joints[0] for trk in trackers], first.groups)
        refined = [(chi, None) for chi, _ in found]
        if first.refinement.iterations:     # every person's Gauss-Newton steps together
            refined = refine_people([e.points for e, _ in built], np.stack([chi for chi, _ in found]),
                                    [e.obs for e, _ in built], first.pinhole, first.body.limits,
                                    first.refinement, first.likelihood.gate_px)
        chis = [trk.after_refinement(e, chi, info)
                for trk, (e, _), (chi, info) in zip(trackers, built, refined, strict=True)]
        t2 = time.perf_counter()
        share = {"observation": (t1 - t0) / len(trackers), "search": (t2 - t1) / len(trackers)}
        out = []
        for trk, (energy, context), chi, (_, trace) in zip(trackers, built, chis, found, strict=True):
            trk.history = [*trk.history[-2:], chi]
            out.append(Estimate(chi=chi, alpha=trk.shaped.alpha,
                                diagnostics=trk.report(energy, context, chi, trace, dict(share))))
        return out

    @staticmethod
    def _batchable(trackers: list[MarkerAPFTracker]) -> bool:
        """Trackers whose searches can run as one batch: two or more, crossover groups, one body,
        landmark set, search and refinement settings and cameras, no particles kept."""
        if len(trackers) < 2:
            return False
        a = trackers[0]
        if not a.groups or a.keep_particles or a.shaped is None:
            return False
        for b in trackers[1:]:
            if (b.body is not a.body or b.settings != a.settings or b.keep_particles or b.shaped is None
                    or b.refinement != a.refinement or b.likelihood.gate_px != a.likelihood.gate_px
                    or (b.rig is not a.rig and b.pinhole != a.pinhole)
                    or b.landmarks.names != a.landmarks.names or not np.array_equal(b.std0, a.std0)
                    or len(b.groups) != len(a.groups)
                    or not all(np.array_equal(g.dofs, h.dofs) and np.array_equal(g.landmarks, h.landmarks)
                               for g, h in zip(a.groups, b.groups, strict=True))):
                return False
        return True

    def _points(self, det: Detections) -> np.ndarray:
        """(L, 3) one person's triangulated keypoints, world m (NaN: not triangulated)."""
        probe = self._probe_tracker()
        X, _ = triangulate_candidates(probe.pinhole, arrange_detections(
            det, probe.landmarks.names, probe.rig, probe.min_confidence), probe.likelihood.gate_px)
        return X

    def _centre(self, det: Detections) -> np.ndarray | None:
        """(3,) median of one person's triangulated keypoints (None: fewer than 3 triangulated)."""
        X = self._points(det)
        return np.nanmedian(X, axis=0) if np.isfinite(X[:, 0]).sum() >= 3 else None

    def _same_person(self, t: Track, det: Detections) -> bool:
        """A track coming back after missed frames takes skeletons only when they triangulate
        within ``options.radius`` of where it coasted."""
        centre = self._centre(det)
        return centre is not None and \
            bool(np.linalg.norm(centre - np.median(self._landmarks(t, t.tracker.predict()), axis=0))
                 < self.options.radius)

    def _births(self, frame: Frame, sk: Skeletons, used: list[set[int]]) -> list[Track]:
        """New people among the skeletons no track took (see the module docstring)."""
        o, probe, det = self.options, self._probe_tracker(), frame.detections
        rest = [np.array(sorted(set(range(len(x))) - used[c]), np.int64)
                for c, x in enumerate(sk.xy)]
        free = Skeletons([x[r] for x, r in zip(sk.xy, rest, strict=True)],
                         [v[r] for v, r in zip(sk.valid, rest, strict=True)],
                         [i[r] for i, r in zip(sk.ids, rest, strict=True)])
        if sum(len(x) > 0 for x in free.xy) < self.min_views:
            self.candidates = []
            return []
        people = associate_people(free, probe.F, self._association_px(), min_views=self.min_views)
        if o.consistency and people:
            if self._reference is not None:
                people = [(p, d) for p, d in people if d <= o.consistency * self._reference]
        people = self._supported(det, free, people)
        # a live track blocks a candidate next to it (a skeleton of its person it did not take),
        # unless it has coasted longer than confirm_frames (a newcomer where someone left)
        centres = [np.median(self._landmarks(t), axis=0) for t in self.tracks
                   if not t.ended and t.missed <= o.confirm_frames]
        seen: list[Candidate] = []
        for person, _, X in people:
            pdet = person_detections(det, free, person)
            centre = np.nanmedian(X, axis=0)
            if any(np.linalg.norm(centre - c) < o.radius for c in centres):
                continue                          # a live track's skeleton it did not take
            before = [k for k in self.candidates if np.linalg.norm(k.centre - centre) < o.radius]
            frames = 1 + max((k.frames for k in before), default=0)
            seen.append(Candidate(centre, frames, pdet))
        born = []
        self.candidates = []
        for k in seen:
            if k.frames >= o.confirm_frames:
                new_id = 1 + max((t.id for t in self.tracks), default=-1)
                t = self._new_track(new_id, frame.index, k.detections)
                self.tracks.append(t)
                self.births.setdefault(frame.index, []).append(t.id)
                born.append(t)
            else:
                self.candidates.append(k)
        return born

    # -- the run's contract (mocap.trackers.contract) ----------------------------------------
    def initializer(self, cache=None) -> PeopleStart:
        return PeopleStart(self)

    def begin(self, frame: Frame, initial: FrameEstimate) -> FrameEstimate:
        return initial          # the people were started by the initializer

    def track(self, frame: Frame) -> FrameEstimate:
        return self.step(frame)

    def final_tracks(self, tracks: Tracks) -> Tracks:
        return self.estimates_by_person()

    # -- results -----------------------------------------------------------------------
    def estimates_by_person(self) -> dict[int, dict[int, Estimate]]:
        """{track id: {frame: estimate}} of every track (ended ones included)."""
        return {t.id: dict(t.estimates) for t in self.tracks}


class PeopleStart(Uncached):
    """The several-people start-up (:meth:`PeopleTracker.start`) as an
    :class:`~mocap.trackers.contract.Initializer`: {track id: initial estimate}; info: its
    seconds. Never cached."""

    def __init__(self, people: PeopleTracker):
        self.people = people

    def __call__(self, frame: Frame) -> tuple[dict[int, Estimate], dict]:
        t = time.perf_counter()
        tracks = self.people.start(frame)
        return {t_.id: t_.estimates[frame.index] for t_ in tracks}, {"seconds": time.perf_counter() - t}
