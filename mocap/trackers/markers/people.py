"""Several people with the marker tracker: one :class:`MarkerAPFTracker` per person, with
identities kept across frames.

Start-up (:meth:`PeopleTracker.start`): the people of the first frame are associated across
views by whole-skeleton epipolar consistency (:mod:`mocap.trackers.markers.associate`); each
person seen in ``min_views`` or more views gets a track (id 0, 1, ... in the association's
order: most views first), initialised by the tracker's own start-up on that person's
detections. ``select`` keeps one of them: ``"all"``, ``"most_views"``, an ``int`` id, or a
point (x, y, z) world metres (the person whose triangulated keypoints lie nearest).

Each frame (:meth:`PeopleTracker.step`): every track predicts its landmarks; in each view
the detector's skeletons are assigned to tracks by the Hungarian method on the median pixel
distance between a skeleton's keypoints and the track's predicted projections (gated at the
likelihood's gate); each track then runs its annealed search on the skeletons assigned to it
only, so a crossing person's keypoints cannot pull a track across. A track without any
assigned skeleton for ``max_missed`` frames ends (the person left). People entering are not
picked up (see the issue note).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from mocap.data.sequence import Detections
from mocap.energy.markers import pinhole_project
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.markers.associate import associate_people, person_detections, skeletons_of
from mocap.trackers.markers.tracker import MarkerAPFTracker


@dataclass
class Track:
    id: int
    tracker: MarkerAPFTracker
    missed: int = 0
    ended: bool = False
    estimates: dict[int, Estimate] = field(default_factory=dict)


def _only(det: Detections, keep: np.ndarray) -> Detections:
    return Detections(det.labels, det.frame[keep], det.view[keep], det.label[keep], det.xy[keep],
                      det.confidence[keep], None if det.person is None else det.person[keep])


class PeopleTracker:
    """make_tracker: () -> a fresh MarkerAPFTracker (same body, rig, settings; own rng)."""

    def __init__(self, make_tracker: Callable[[], MarkerAPFTracker],
                 select: str | int | Sequence[float] = "all",
                 min_views: int = 2, max_missed: int = 10):
        self.make_tracker, self.select = make_tracker, select
        self.min_views, self.max_missed = min_views, max_missed
        self.tracks: list[Track] = []

    def start(self, frame: Frame) -> list[Track]:
        probe = self.make_tracker()
        probe._landmarks_for(frame)
        det = frame.detections
        sk = skeletons_of(det, probe.landmarks.names, probe.rig)
        if sk is None:
            raise ValueError("several people need detections grouped into skeletons (Detections.person)")
        people = associate_people(sk, probe.F, probe.init.association_px or probe.likelihood.gate_px,
                                  min_views=self.min_views)
        if not people:
            raise ValueError(f"frame {frame.index}: no person seen consistently in {self.min_views}+ views")
        tracks = []
        for n, (person, _) in enumerate(people):
            trk = self.make_tracker()
            sub = Frame(frame.index, detections=person_detections(det, sk, person))
            chi, alpha = trk.initial_estimate(sub)
            trk.initialize(chi, alpha)
            t = Track(n, trk)
            t.estimates[frame.index] = Estimate(chi=chi, alpha=alpha, diagnostics={"initial": True})
            tracks.append(t)
        self.tracks = self._chosen(tracks)
        return self.tracks

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
        return trk.landmarks.positions(trk.shaped, chi[None])[0].astype(np.float64)

    def assign(self, frame: Frame, live: list[Track]) -> list[np.ndarray]:
        """Per live track, the (N,) bool rows of the frame's detections assigned to it."""
        det = frame.detections
        probe = live[0].tracker
        names = probe.landmarks.names
        sk = skeletons_of(det, names, probe.rig)
        keep = [np.zeros(len(det), bool) for _ in live]
        if sk is None:                                      # no grouping: everyone sees everything
            return [np.ones(len(det), bool) for _ in live]
        pred = np.stack([self._landmarks(t, t.tracker.predict()) for t in live])     # (T, L, 3)
        u, depth = pinhole_project(probe.pinhole, pred)                             # (T, L, C, 2)
        gate = probe.likelihood.gate_px
        for c in range(len(probe.rig)):
            S = len(sk.xy[c])
            if not S:
                continue
            cost = np.full((len(live), S), 1e9)
            for i in range(len(live)):
                for j in range(S):
                    ok = sk.valid[c][j] & (depth[i, :, c] > 0)
                    if ok.sum() >= 3:
                        cost[i, j] = np.median(np.linalg.norm(sk.xy[c][j][ok] - u[i, ok, c], axis=1))
            rows, cols = linear_sum_assignment(cost)
            for i, j in zip(rows, cols, strict=True):
                if cost[i, j] < gate:
                    keep[i] |= (det.view == c) & (det.person == sk.ids[c][j])
        return keep

    def step(self, frame: Frame) -> dict[int, Estimate]:
        """{track id: estimate} for the tracks still live."""
        live = [t for t in self.tracks if not t.ended]
        if not live:
            return {}
        out = {}
        for t, rows in zip(live, self.assign(frame, live), strict=True):
            if not rows.any():
                t.missed += 1
                t.ended = t.missed > self.max_missed
            else:
                t.missed = 0
            est = t.tracker.step(Frame(frame.index, detections=_only(frame.detections, rows)))
            t.estimates[frame.index] = est
            out[t.id] = est
        return out
