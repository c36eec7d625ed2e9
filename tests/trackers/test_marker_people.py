"""Several people with births and deaths (mocap/trackers/markers/people.py, ``marker_people``):
a person entering later is picked up within 10 frames, a person leaving ends its track, two
people crossing keep their identities; synthetic keypoints grouped per person, 5 views."""

import numpy as np
import pytest

from mocap.body.skeletons import LAYOUTS
from mocap.cameras import rig_from_config
from mocap.data.crowd import CROWD_RIG, crossing_scene, crowd_detections, straight_walk
from mocap.data.sequence import Sequence
from mocap.eval.people_metrics import people_scores
from mocap.trackers.presets import make_tracker, preset_settings
from mocap.trackers.run import frame_of

LABELS = [n for n in LAYOUTS["BODY_25B"] if n is not None]
#: small budgets: these tests check who is tracked, not how precisely
FAST = {"particles": 30, "layers": 3, "init": {"particles": 60, "passes": 2, "layers": 5}}


def run(body, seq, frames, **people):
    tracker = make_tracker("marker_people", body=body, rig=seq.rig, rng=np.random.default_rng(0),
                           people=people, **FAST)
    tracker.start(frame_of(seq, 0))
    for f in range(1, frames):
        tracker.step(frame_of(seq, f))
    return tracker


def track_joints(body, tracker, frames):
    """(F, P, J, 3) joints of every track (NaN where it has no estimate), and the track ids."""
    ids = [t.id for t in tracker.tracks]
    out = np.full((frames, len(ids), body.num_joints, 3), np.nan)
    for p, t in enumerate(tracker.tracks):
        for f, est in t.estimates.items():
            out[f, p] = body.shaped(est.alpha).pose(est.chi).joints[0]
    return out, ids


def scene(body, walks, present, seed=0):
    """Sequence of people walking (start, end, yaw) over present's frames, and their joints
    (F, N, J, 3) (NaN where absent)."""
    F = present.shape[1]
    chis = np.stack([straight_walk(body, F, a, b, yaw, seed + n) for n, (a, b, yaw) in enumerate(walks)])
    alphas = np.random.default_rng(seed).normal(0, 0.8, (len(walks), body.num_shape))
    rig = rig_from_config(CROWD_RIG)
    det, _ = crowd_detections(body, rig, chis, alphas, LABELS, noise_px=1.0, seed=seed, present=present)
    joints = np.stack([body.shaped(a).pose(c).joints for c, a in zip(chis, alphas, strict=True)])
    joints = np.where(present[..., None, None], joints, np.nan).transpose(1, 0, 2, 3)
    return Sequence(name="scene", rig=rig, fps=25, detections=det), joints


def test_a_person_entering_at_frame_k_is_tracked_within_10_frames(body):
    F, k = 9, 3
    present = np.ones((2, F), bool)
    present[1, :k] = False
    seq, truth = scene(body, [((-0.8, 0.0), (-0.5, 0.0), 0.0), ((0.9, 0.6), (0.6, 0.6), np.pi)], present)
    tracker = run(body, seq, F)
    assert tracker.births[0] == [0] and len(tracker.tracks) == 2
    (born,) = [f for f, ids in tracker.births.items() if ids == [1]]
    assert k < born <= k + 10
    est, _ = track_joints(body, tracker, F)
    scores = people_scores(est, truth, [])
    entrant = scores["people"][1]
    assert entrant["first_frame"] == k and entrant["latency_frames"] <= 10
    # confirmed over confirm_frames consecutive frames (the default 3): from k + 2, not before
    assert entrant["first_tracked_frame"] == k + 2 and entrant["mpjpe_mm"] < 60
    assert scores["switches"] == 0


def test_a_person_leaving_ends_its_track_and_the_other_goes_on(body):
    F, last = 9, 3
    present = np.ones((2, F), bool)
    present[1, last + 1:] = False
    seq, truth = scene(body, [((-0.8, 0.0), (-0.5, 0.0), 0.0), ((0.9, 0.6), (0.6, 0.6), np.pi)], present)
    tracker = run(body, seq, F, max_missed=2)
    est, ids = track_joints(body, tracker, F)
    scores = people_scores(est, truth, [])
    leaver = tracker.tracks[ids.index(scores["assignment"][1])]
    stayer = tracker.tracks[ids.index(scores["assignment"][0])]
    assert leaver.ended and max(leaver.estimates) == last          # the coasted frames are dropped
    assert tracker.deaths == {last + 2 + 1: [leaver.id]}              # missed for more than max_missed
    assert not stayer.ended and max(stayer.estimates) == F - 1
    assert len(tracker.tracks) == 2 and scores["switches"] == 0


def test_two_people_crossing_keep_their_identities_with_births_on(body):
    F = 16
    chis, alphas = crossing_scene(body, F, people=2, gap=0.3)
    rig = rig_from_config(CROWD_RIG)
    det, _ = crowd_detections(body, rig, chis, alphas, LABELS, noise_px=1.0, seed=0)
    seq = Sequence(name="crossing", rig=rig, fps=25, detections=det)
    truth = np.stack([body.shaped(a).pose(c).joints for c, a in zip(chis, alphas, strict=True)])
    truth = truth.transpose(1, 0, 2, 3)
    # the walks start 2.4 m apart and cross at frame F // 2
    assert np.linalg.norm(truth[F // 2, 0, 0, :2] - truth[F // 2, 1, 0, :2]) < 0.4
    tracker = run(body, seq, F)
    est, ids = track_joints(body, tracker, F)
    scores = people_scores(est, truth, [])
    assert len(ids) == 2, "a crossing made a new track"
    assert scores["switches"] == 0
    assert all(p["tracked_frames"] == F and p["mpjpe_mm"] < 60 for p in scores["people"])


def test_people_settings_are_checked_with_one_line_errors():
    with pytest.raises(ValueError, match=r"people\.confirm_frames = 0 is out of range \(allowed: an integer"):
        preset_settings("marker_people", {"people": {"confirm_frames": 0}})
    with pytest.raises(ValueError, match=r"people\.min_views = 1 is out of range") as err:
        preset_settings("marker_people", {"people": {"min_views": 1}})
    assert "\n" not in str(err.value)
    s = preset_settings("marker_people", {"people": {"max_missed": 4}, "particles": 50})
    assert s.people.max_missed == 4 and s.people.confirm_frames == 3 and s.particles == 50


def test_a_short_occlusion_keeps_the_identity_and_makes_no_new_track(body):
    F = 10
    present = np.ones((2, F), bool)
    present[1, 4:7] = False                    # person 1 unseen in every view for 3 frames
    seq, truth = scene(body, [((-0.8, 0.0), (-0.5, 0.0), 0.0), ((0.9, 0.6), (0.6, 0.6), np.pi)], present)
    tracker = run(body, seq, F)
    assert len(tracker.tracks) == 2 and not tracker.deaths
    est, ids = track_joints(body, tracker, F)
    scores = people_scores(est, truth, [])
    back = scores["people"][1]
    assert scores["switches"] == 0 and back["tracked_frames"] == F - 3 and back["mpjpe_mm"] < 60
    occluded = tracker.tracks[ids.index(scores["assignment"][1])]
    assert occluded.missed == 0 and sorted(occluded.estimates) == list(range(F))     # it coasted
